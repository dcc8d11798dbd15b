"""Compiled CasADi code cached on disk, so that only the first start pays for gcc.

The cache itself (hashing, atomic compile, ``$SPLITTER_CACHE_DIR``) lives in
:mod:`splitter_model.codegen`, shared with the simulator's compiled kernels; this
module adds loading the compiled functions back as CasADi externals.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from splitter_model.codegen import (
    COMPILE_TIMEOUT_S,
    DEFAULT_FLAGS,
    CompilationError,
    compiled_library,
    compiler_available,
    default_cache_dir,
)

__all__ = [
    "COMPILE_TIMEOUT_S",
    "DEFAULT_FLAGS",
    "CompilationError",
    "compiled_functions",
    "compiled_library",
    "compiler_available",
    "default_cache_dir",
]


def compiled_functions(
    name: str,
    functions: Sequence[ca.Function],
    cache_dir: Path | None = None,
    flags: Sequence[str] = DEFAULT_FLAGS,
) -> list[ca.Function]:
    """The ``functions`` compiled into one cached library, loaded back as externals."""

    def write(path: Path) -> None:
        generator = ca.CodeGenerator(path.name, {"with_header": False})
        for f in functions:
            generator.add(f)
        generator.generate(str(path.parent) + os.sep)

    library = compiled_library(name, write, cache_dir, flags)
    return [ca.external(f.name(), str(library)) for f in functions]
