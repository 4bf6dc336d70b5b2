"""Print the requirements of optional-dependency groups of pyproject.toml, one per line.

``make test`` installs them with pip beside an existing editable install, so only what is
missing gets installed (reinstalling ``.[test,bench]`` would rebuild the package itself).
Usage: ``python tools/extras.py test bench live``.
"""

import sys
import tomllib
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def main(names: list[str]) -> int:
    groups = tomllib.loads(PYPROJECT.read_text())["project"]["optional-dependencies"]
    unknown = [n for n in names if n not in groups]
    if unknown:
        print(f"{PYPROJECT}: no extra {', '.join(unknown)} (extras: {', '.join(groups)})",
              file=sys.stderr)  # fmt: skip
        return 2
    for name in names:
        print("\n".join(groups[name]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
