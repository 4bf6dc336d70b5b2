"""Subcommands of ``gyrotens``; see ``gyrohost.cli``."""
