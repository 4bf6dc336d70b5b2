"""The real-time run loop's effects on the filter's consistency, one at a time.

``python -m studies.estimator_effects [--runs 3] [--duration 3] [--delay-ms 2] [--case NAME]``:
each case of :data:`gyrohost.sil.effects.CASES` over ``--runs`` seeds on the simulated clock,
summarised against the bounds of the runs' average.
"""

import argparse

from gyrohost.sil.effects import CASES, score_with_effects
from gyrohost.sil.montecarlo import summarise
from gyrohost.sil.options import DEFAULT_CONFIG


def _value(text):
    try:
        return float(text)
    except ValueError:
        return text


def main(argv=None) -> int:
    from gyrohost.config import load_rig_config

    parser = argparse.ArgumentParser(prog="python -m studies.estimator_effects")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--duration", type=float, default=3.0, help="s")
    parser.add_argument("--delay-ms", type=float, default=2.0, help="mean arrival delay, ms")
    parser.add_argument("--late-ms", type=float, default=1.0, help="mean tick lateness, ms")
    parser.add_argument("--case", choices=sorted(CASES), action="append")
    parser.add_argument("--key", action="append", default=[], help="estimator KEY=VALUE")
    args = parser.parse_args(argv)
    config = load_rig_config(DEFAULT_CONFIG)
    overrides = {k: _value(v) for k, v in (kv.split("=", 1) for kv in args.key)}
    for name in args.case or CASES:
        effects = CASES[name]
        results = [
            score_with_effects(
                config,
                s,
                effects,
                args.duration,
                1e-3 * args.delay_ms,
                1e-3 * args.late_ms,
                overrides,
            )
            for s in range(args.first_seed, args.first_seed + args.runs)
        ]
        print(f"--- {name}: {effects.label()}; {args.runs} runs")
        summarise(results, f"[{name}] ")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
