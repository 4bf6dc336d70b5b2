"""What a run records about itself in ``meta.json``: the set-up before it starts, the summary
once it has reached the safe state."""

from dataclasses import asdict

from gyrohost.run.ticker import jitter_line
from gyrohost.simrig.errors import RigProcessError
from gyrotensegrity import __version__
from gyrotensegrity.attitude import angle_between


def run_meta(loop) -> dict:
    """``meta.json`` at the start: software, rig configuration, scene, schedule, settings."""
    return {
        "software": {"gyrotens": __version__},
        "rig_config": asdict(loop.config),
        "scene": str(loop.config.scene_path),
        "schedule": loop.schedule.to_dict(),
        **({"target": loop.maneuver.target.to_dict()} if loop.maneuver else {}),
        "settings": asdict(loop.settings),
        "time": "t_s: host time since the start of the run (time.monotonic), s",
        **loop.extra_meta,
    }


def run_summary(loop, reason: str, safe: dict) -> dict:
    """The ``summary`` of ``meta.json``: outcome, safe state, loop timing, rows, tilts.

    Also logs the timing line as a ``timing`` event.
    """
    timing = loop.ticker.timer.stats()
    out = {
        "reason": reason,
        "completed": reason == "completed",
        "safe_state": safe,
        "loop": timing,
        "rows": {name: s.rows for name, s in loop.log.streams.items()},
        "not_fused": loop.dispatcher.skipped,
        "servo_comm_retries": getattr(loop.servo_worker, "comm_errors_total", 0),
        "links": link_counts(loop),
        "duration_s": loop.now(),
        "schedule_purpose": loop.schedule.purpose,
    }
    out.update(loop.final)
    if loop.wheels is not None:  # how near the host's pauses came to the board's fail-safe
        limit_s = loop.settings.heartbeat_ms / 1e3
        out["wheel_board_silence_s"] = {"max": loop.wheels.silence_max_s, "limit": limit_s}
    if loop.estimator is not None and loop.estimator.health is not None:  # it ran
        out["estimator"] = {
            **loop.estimator.health,
            "lag_s": loop.estimator.lag_table(),
            "required": loop.estimate_required,
        }
    if loop.maneuver is not None:
        out["maneuver"] = loop.maneuver.summary()
        out.update(landing_errors(loop.maneuver, out))
    if loop.rig is not None:
        try:
            stats = loop.rig.stats()
            out["rig"], out["rig_real_time"] = stats["lines"], stats["real_time"]
        except RigProcessError as exc:
            out["rig"] = [str(exc)]
        lost = real_time_lost(out)
        if lost:
            loop.event("warning", lost)
    loop.event("timing", jitter_line(timing))
    return out


def landing_errors(maneuver, summary: dict) -> dict:
    """The truth's distance from the maneuver's target at the end of the schedule and after
    settling (simulated rig): the tilt's difference (``tilt_end_truth_error_rad``, ...) or the
    geodesic angle of the body attitude (``attitude_end_truth_error_rad``, ...), rad."""
    target = maneuver.target
    out = {}
    for key in ("end", "settled"):
        if target.attitude_rpy_rad is None and f"tilt_{key}_truth_rad" in summary:
            out[f"tilt_{key}_truth_error_rad"] = summary[f"tilt_{key}_truth_rad"] - target.tilt_rad
        truth = summary.get(f"attitude_{key}", {}).get("truth")
        if target.attitude_rpy_rad is not None and truth is not None:
            q = maneuver.replanner.goal.target
            out[f"attitude_{key}_truth_error_rad"] = float(angle_between(q, truth["quaternion"]))
    return out


def link_counts(loop) -> dict:
    """What each device's link lost during the run: the IMU parser's bad checksums, unknown
    frame types and frames missing from its sequence; the wheel board's frames dropped by kind
    (``bad_crc``, ...), the gaps in its telemetry's sequence numbers (a reboot restarts them:
    one gap) and the frames missing there, telemetry the client's queue dropped."""
    out = {}
    stats = getattr(loop.imu, "stats", None)
    if stats is not None:
        out["imu"] = {"bad_checksums": stats.corrupt_frames, "unknown_types": stats.unknown_type,
                      "frames_dropped": stats.dropped_frames}  # fmt: skip
    decoder = getattr(loop.wheels, "decoder", None)
    if decoder is not None:
        handler = getattr(loop.dispatcher, "handlers", {}).get("wheels")
        out["wheels"] = {
            "crc_errors": decoder.dropped.get("bad_crc", 0),
            "frames_dropped": dict(decoder.dropped),
            "sequence_gaps": getattr(handler, "sequence_gaps", 0),
            "frames_lost": getattr(handler, "frames_lost", 0),
            "queue_dropped": loop.wheels.telemetry_dropped,
        }
    return out


def link_lines(summary: dict) -> list[str]:
    """One line per device link that lost frames (a run's ``summary``); none when nothing was
    lost."""
    lines = []
    imu = summary.get("links", {}).get("imu", {})
    if any(imu.values()):
        lines.append(f"IMU link: {imu['bad_checksums']} bad checksums, {imu['unknown_types']} "
                     f"unknown frame types, {imu['frames_dropped']} frames dropped")  # fmt: skip
    wheels = summary.get("links", {}).get("wheels", {})
    lost = {k: v for k, v in wheels.items() if k not in ("crc_errors", "frames_dropped") and v}
    if wheels.get("frames_dropped") or lost:
        dropped = ", ".join(f"{n} {kind}" for kind, n in wheels["frames_dropped"].items())
        lines.append(
            f"wheel board link: {wheels['crc_errors']} CRC errors ({dropped or 'no frame'} "
            f"dropped), {wheels['sequence_gaps']} sequence gaps ({wheels['frames_lost']} frames "
            f"lost), {wheels['queue_dropped']} dropped by the host's queue"
        )
    if summary.get("servo_comm_retries"):
        lines.append(f"servo bus: {summary['servo_comm_retries']} reads or writes retried")
    return lines


def sources_line(summary: dict) -> str | None:
    """The estimator's samples per source (a run's ``summary``): fused, rejected by the gate,
    out of order (and of those too old to fuse), time-outs; None if the estimator never ran."""
    sources = summary.get("estimator", {}).get("sources", {})
    if not sources:
        return None
    parts = [
        f"{name} {c['accepted']} fused, {c['rejected']} rejected, {c['out_of_order']} out of "
        f"order ({c['stale']} stale), {c['timeouts']} time-outs"
        for name, c in sources.items()
    ]
    return "estimator samples: " + "; ".join(parts)


def real_time_lost(summary: dict) -> str | None:
    """What it means for the log that the simulated rig's truth did not keep real time, by a
    run's ``summary`` (its ``rig_real_time``); None where it did, or no simulated rig ran."""
    real_time = summary.get("rig_real_time")
    if real_time is None or real_time["kept"]:
        return None
    return (
        f"the simulated rig's truth did not keep real time ({100 * real_time['late_share']:.0f} "
        f"% of its steps late, up to {1e3 * real_time['max_lag_s']:.0f} ms; slipped "
        f"{real_time['slipped_s']:.2f} s): the CPU was too loaded, so the log's stamps and its "
        "physics disagree; do not identify from it (close other programs and record again)"
    )
