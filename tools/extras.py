"""Print the requirements of optional-dependency groups of pyproject.toml, one per line.

``make test`` installs them with pip beside an existing editable install, so only what is
missing gets installed (reinstalling ``.[test,bench]`` would rebuild the package itself). A group
that names other groups of the project (``gyrotensegrity[sweep]``) is expanded into their
requirements for the same reason.
Usage: ``python tools/extras.py test bench live``.
"""

import re
import sys
from pathlib import Path

from gyrotensegrity.compat import tomllib

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def requirements(project: dict, names: list[str]) -> list[str]:
    """The requirements of the extras ``names``, own extras expanded, each listed once.

    Raises
    ------
    KeyError
        An extra that the project does not define (its name).
    """
    groups = project["optional-dependencies"]
    own = re.compile(rf"{re.escape(project['name'])}\[([^\]]+)\]$")
    out: list[str] = []
    pending = list(names)
    seen: set[str] = set()
    while pending:
        name = pending.pop(0).strip()
        if name in seen:
            continue
        seen.add(name)
        if name not in groups:
            raise KeyError(name)
        for req in groups[name]:
            match = own.match(req.replace(" ", ""))
            if match:
                pending.extend(match.group(1).split(","))
            elif req not in out:
                out.append(req)
    return out


def main(names: list[str]) -> int:
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    try:
        reqs = requirements(project, names)
    except KeyError as exc:
        extras = ", ".join(project["optional-dependencies"])
        print(f"{PYPROJECT}: no extra {exc.args[0]} (extras: {extras})", file=sys.stderr)
        return 2
    print("\n".join(reqs))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
