"""Dynamics of gyroscopic tensegrity structures (Goyal, Chen, Majji, Skelton).

Depends on numpy and scipy only.
"""

__version__ = "0.1.0"
