"""The text of a TOML or JSON input file (scene, rig configuration, schedule, estimator settings).

One reader for every loader, so each refuses a file that is not UTF-8 text in one line naming
the file: a binary file (a NUL byte, or bytes that are not UTF-8) or a file that cannot be read.
A leading UTF-8 byte-order mark, which some editors write, is dropped: the rest is read as if it
were not there.
"""

from pathlib import Path

from .compat import tomllib

BOM = "\ufeff"


class TextFileError(ValueError):
    """A file is not readable UTF-8 text; the message names the file and what is wrong."""


def read_text(path: str | Path) -> str:
    """The UTF-8 text of ``path``, without a leading byte-order mark.

    Raises
    ------
    TextFileError
        The file cannot be read (missing, a folder, no permission), holds a NUL byte (a binary
        file) or is not valid UTF-8; the message names the file and the offset of the first bad
        byte.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise TextFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    nul = data.find(b"\0")
    if nul >= 0:
        raise TextFileError(f"{path}: a binary file (NUL byte at offset {nul}), not UTF-8 text")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise TextFileError(
            f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}): "
            "a binary file or another encoding; save it as UTF-8"
        ) from None
    return text.removeprefix(BOM)


def read_toml(path: str | Path, error: type[Exception]) -> dict:
    """The parsed TOML file at ``path``.

    Raises
    ------
    error
        The file is not readable UTF-8 text (:func:`read_text`) or not valid TOML; one line
        naming the file (``<path>: invalid TOML: ...``).
    """
    try:
        return tomllib.loads(read_text(path))
    except TextFileError as exc:
        raise error(str(exc)) from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: invalid TOML: {exc}") from None
