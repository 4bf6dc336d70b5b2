"""Identification: the rig's dynamics model fitted to its run logs (docs/identification.md)."""
