"""Build of the optional compiled kernel (gyrotensegrity._fastkernel); everything else is in
pyproject.toml. ``optional=True``: without a C compiler the install still succeeds and
gyrotensegrity.fast falls back to its numpy path."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "gyrotensegrity._fastkernel",
            ["model/gyrotensegrity/_fastkernel.c"],
            extra_compile_args=["-O3", "-std=c99"],
            optional=True,
        )
    ]
)
