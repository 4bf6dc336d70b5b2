"""What a run records about itself in ``meta.json``: the set-up before it starts, the summary
once it has reached the safe state."""

from dataclasses import asdict

from gyrohost.run.ticker import jitter_line
from gyrohost.simrig.errors import RigProcessError
from gyrotensegrity import __version__


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
            # an identification run's scene is the one still to be identified
            "required": loop.schedule.purpose != "identification",
        }
    if loop.maneuver is not None:
        out["maneuver"] = loop.maneuver.summary()
        target = loop.maneuver.target.tilt_rad
        for key in ("tilt_end", "tilt_settled"):
            if f"{key}_truth_rad" in out:
                out[f"{key}_truth_error_rad"] = out[f"{key}_truth_rad"] - target
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
