"""A package's names imported on first use (PEP 562), for packages whose submodules load heavy
libraries (SciPy, pycolmap) that a command's ``--help`` never needs.

    __getattr__, __dir__, __all__ = lazy_exports.attach(__name__, {
        "rp_jax.mapsum.kcover": ("greedy_kcover", "kcover_keep"), ...}, eager=("partition",))

A name that is also a submodule's (``rp_jax.mapsum.partition``) must be imported eagerly in
the package and listed in ``eager``: the import system binds a submodule to its package's
name when it first loads it, which would hide a lazily imported function of that name.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence

__all__ = ["attach"]


def attach(package: str, homes: Mapping[str, Sequence[str]], eager: Sequence[str] = ()
           ) -> tuple[Callable[[str], object], Callable[[], list[str]], list[str]]:
    """``(__getattr__, __dir__, __all__)`` of ``package``.

    Args:
      package: the package's ``__name__``.
      homes: module -> the names the package re-exports from it.
      eager: names the package imports itself (they are only added to ``__all__``).
    """
    where = {name: module for module, names in homes.items() for name in names}
    names = sorted([*where, *eager])

    def __getattr__(name: str) -> object:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(where[name]), name)
        setattr(sys.modules[package], name, value)  # asked once
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__, names
