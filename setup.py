"""Build turbinefit's compiled kernels (src/turbinefit/_kernels.c).

Everything else is declared in pyproject.toml. The kernels are optional: they are built
with OpenMP where the compiler supports it, without it otherwise, and if no C compiler
works the install still succeeds and turbinefit uses its numpy implementation (slower,
same results; see turbinefit/_native.py).
"""

from __future__ import annotations

import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """build_ext that tries OpenMP first and never fails the install."""

    def build_extension(self, ext: Extension) -> None:
        msvc = self.compiler.compiler_type == "msvc"
        openmp = (["/openmp"], []) if msvc else (["-fopenmp"], ["-fopenmp"])
        base_args = list(ext.extra_compile_args)
        base_link = list(ext.extra_link_args)
        for compile_extra, link_extra in (openmp, ([], [])):
            ext.extra_compile_args = base_args + compile_extra
            ext.extra_link_args = base_link + link_extra
            try:
                super().build_extension(ext)
                return
            except Exception as exc:  # any compiler failure
                print(f"turbinefit: building {ext.name} with {compile_extra or 'no'} flags "
                      f"failed ({exc})", file=sys.stderr)
        print("turbinefit: compiled kernels not built; the numpy implementation will be used",
              file=sys.stderr)


setup(
    ext_modules=[Extension(
        "turbinefit._kernels", ["src/turbinefit/_kernels.c"],
        extra_compile_args=[] if sys.platform == "win32" else ["-O3", "-std=c99"],
    )],
    cmdclass={"build_ext": OptionalBuildExt},
)
