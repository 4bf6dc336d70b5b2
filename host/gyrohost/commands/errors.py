"""The one error a subcommand raises for a user's mistake."""

from gyrohost.errors import GyrohostError


class CliError(GyrohostError, ValueError):
    """A user-facing error: printed as ``gyrotens: error: <message>``, exit status 2."""
