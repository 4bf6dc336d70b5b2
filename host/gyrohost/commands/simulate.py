"""``gyrotens simulate SCENE -o RUN.npz``: run a scene through the dynamics model.

``SCENE`` is a scene file or the name of a shipped scene (``dbar-gyro``). The dynamics are
evaluated by the fast path (:mod:`gyrotensegrity.fast`, the compiled kernel where built) unless
``--reference`` asks for the readable reference :func:`gyrotensegrity.rhs`; both give the same
result to round-off (docs/performance.md).
"""

import sys
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a scene file and write a run file (.npz)")
    p.add_argument(
        "scene", help="scene file (TOML, docs/scene-format.md) or shipped name (dbar-gyro)"
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="run file to write (.npz)")
    p.add_argument("--integrator", help="rk4, rk4-projected, dop853, rk45, radau or bdf")
    p.add_argument("--dt", type=float, help="fixed step, s (rk4, rk4-projected)")
    p.add_argument("--rtol", type=float, help="relative tolerance (adaptive integrators)")
    p.add_argument("--atol", type=float, help="absolute tolerance (adaptive integrators)")
    p.add_argument("--duration", type=float, help="simulated time, s (default: the scene's)")
    p.add_argument(
        "--reference",
        action="store_true",
        help="evaluate the dynamics by the readable reference path (slower; default: fast path)",
    )
    p.set_defaults(func=run)


class _Progress:
    """A one-line progress bar on a terminal; silent otherwise."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr  # the current stderr, not the one at import
        self.enabled = self.stream.isatty()
        self.last = -1

    def __call__(self, t, duration):
        pct = int(100 * min(t / duration, 1.0))
        if self.enabled and pct != self.last:
            bar = "#" * (pct // 4)
            self.stream.write(f"\r[{bar:<25}] {pct:3d} %  t = {t:.3f} s")
            self.stream.flush()
            self.last = pct

    def close(self):
        if self.enabled:
            self.stream.write("\n")


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.resources import ResourceError, resolve
    from gyrotensegrity import Model, SceneError, SimulationError, load_scene, simulate
    from gyrotensegrity.integrators import NAMES

    if args.integrator and args.integrator not in NAMES:
        raise CliError(f"unknown integrator '{args.integrator}' (one of: {', '.join(NAMES)})")
    for name in ("dt", "rtol", "atol", "duration"):
        value = getattr(args, name)
        if value is not None and not value > 0.0:
            raise CliError(f"--{name} must be positive, got {value}")
    try:
        model = Model(load_scene(resolve("scene", args.scene)))
    except (ResourceError, SceneError) as exc:
        raise CliError(str(exc)) from None
    print(f"{args.scene}: {model.describe()}")
    progress = _Progress()
    try:
        result = simulate(
            model,
            duration=args.duration,
            integrator=args.integrator,
            dt=args.dt,
            rtol=args.rtol,
            atol=args.atol,
            progress=progress,
            fast=not args.reference,
        )
    except SceneError as exc:  # an option the chosen path refuses
        progress.close()
        raise CliError(str(exc)) from None
    except SimulationError as exc:
        progress.close()
        if exc.partial is not None:
            exc.partial.save(args.out)
            print(f"partial run written to {args.out}", file=sys.stderr)
        print(f"gyrotens simulate: error: {exc}", file=sys.stderr)
        return 1
    progress.close()
    result.save(args.out)
    m = result.meta
    print(
        f"wrote {args.out}: {len(result['t'])} samples, {m['integrator']}, "
        f"{'fast' if m['fast'] else 'reference'} path, {m['wall_time_s']:.2f} s"
    )
    return 0
