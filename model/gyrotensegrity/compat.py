"""What differs between the Python versions the package runs on (3.10 to 3.13).

``tomllib`` joined the standard library in Python 3.11; on 3.10 its PyPI release ``tomli`` (the
same parser, a dependency there) stands in.
"""

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

__all__ = ["tomllib"]
