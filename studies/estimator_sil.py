"""The EKF's consistency on the simulated rig's truth model and emulators, over seeds.

``python -m studies.estimator_sil [--runs 20] [--realtime] [...]``: what ``gyrotens sil`` runs
(the same options), kept here so that its figures land in a dated report beside the other
studies'.
"""

import argparse

from gyrohost.sil.options import add_arguments
from gyrohost.sil.scoring import report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.estimator_sil")
    add_arguments(parser)
    report(parser.parse_args(argv))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
