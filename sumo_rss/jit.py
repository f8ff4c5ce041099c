"""Functions written once for two paths: numpy over arrays and numba over scalars.

The RSS formulas (:mod:`sumo_rss.rss.formulas`) and the forward simulation's controllers are used vectorised by
the auditor and the policy costs, and compiled into the planner's forward-simulation kernel
(:mod:`sumo_rss.planner.behavior.kernel`). A function decorated with :func:`jitable` stays an ordinary Python
function; once :func:`register` has run, numba code may call it too (numba's ``register_jitable``). Its body may use
only what numpy over arrays and numba over scalars both accept: arithmetic, comparisons, ``np.maximum``,
``np.minimum``, ``np.abs``, ``np.sqrt``, ``np.tan``, ``np.arctan``, ``np.arctan2``, ``np.tanh``, ``np.isinf``, and
:func:`select` / :func:`as_float` in place of ``np.where`` / ``np.asarray(x, dtype=float)``. Its parameter
objects (``p.lon_brake_min``) are dataclasses in numpy code and named tuples of floats in the kernel
(:data:`RssRow`).

numba is imported only by :func:`register` (a kernel module's import): by the planner, and by the auditor's junction
situations (:mod:`sumo_rss.rss.junction_kernel`, imported at their first call).

**Compiled-code cache.** The kernel is compiled with ``cache=True``. numba checks a cached function only against
its own source file, not against the files of the functions it calls (numba's documented limit): a cache built
before an edit of formulas.py would be loaded as if current. The package's compiled functions therefore use a
cache whose stamp is their own file's and a hash of every sumo_rss module that defines jitable or kernel functions
(:func:`cache_sources`), in numba's usual places: ``NUMBA_CACHE_DIR`` if set, else ``__pycache__`` beside the
source if that directory is writable, else the user-wide ``$XDG_CACHE_HOME/numba`` or ``~/.cache/numba`` (a
read-only install). Where none is writable numba cannot cache, and each process compiles the kernel anew.
"""
from __future__ import annotations

import functools
import hashlib
import re
from collections import namedtuple
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .rss.params import PARAM_NAMES

RssRow = namedtuple("RssRow", PARAM_NAMES)
"""One vehicle's RSS parameters as floats, the form the kernel passes to the formulas (fields of RssParams)."""

def rss_row(table: np.ndarray, j: int) -> RssRow:
    """Row ``j`` of an [n, fields] table of RSS parameters (columns in PARAM_NAMES' order) as an :data:`RssRow`."""
    return RssRow(table[j, 0], table[j, 1], table[j, 2], table[j, 3], table[j, 4], table[j, 5], table[j, 6],
                  table[j, 7], table[j, 8], table[j, 9])


_JITABLE: list[tuple[Callable, Callable]] = []  # (what numba code calls, the function it compiles)
_KERNEL_MODULES: set[str] = set()
_registered = False
PACKAGE = Path(__file__).resolve().parent
JIT_OPTIONS = {"error_model": "numpy"}  # float errors give inf/nan as in numpy (both branches of a select run)


def select(condition: Any, a: Any, b: Any) -> np.ndarray:
    """``np.where(condition, a, b)``; in numba code over scalars ``a if condition else b``."""
    return np.where(condition, a, b)


def as_float(x: Any) -> np.ndarray:
    """``np.asarray(x, dtype=float)``; in numba code over scalars ``float(x)``."""
    return np.asarray(x, dtype=float)


def jitable(fn: Callable | None = None, *, quiet: bool = False) -> Callable:
    """Mark ``fn`` (written for both paths, see the module's docstring) as callable from numba code. Returns it
    unchanged, or with ``quiet`` wrapped so that numpy's floating-point warnings are off while it runs (its
    ``select``s compute both branches, and the unused one may divide by zero)."""
    def mark(fn: Callable) -> Callable:
        @functools.wraps(fn)
        def without_warnings(*args: Any, **kwargs: Any) -> Any:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                return fn(*args, **kwargs)
        target = without_warnings if quiet else fn
        _JITABLE.append((target, fn))
        if _registered:
            _register_one(target, fn)
        return target
    return mark if fn is None else mark(fn)


def compiled_as(target: Callable) -> Callable:
    """Decorator: numba code that calls ``target`` (a numpy-only function) compiles the decorated scalar function in
    its place."""
    def mark(fn: Callable) -> Callable:
        _JITABLE.append((target, fn))
        if _registered:
            _register_one(target, fn)
        return fn
    return mark


def kernel(fn: Callable) -> Callable:
    """Compile ``fn`` with numba (lazily, at its first call; ``cache=True``, numpy's error model); it may call
    every :func:`jitable` function."""
    register()
    import numba

    _KERNEL_MODULES.add(fn.__module__)
    return numba.njit(cache=True, **JIT_OPTIONS)(fn)


def register() -> None:
    """Make every :func:`jitable` function (and :func:`select`, :func:`as_float`) callable from numba code and
    install the kernel's cache locator. Imports numba; idempotent."""
    global _registered
    if _registered:
        return
    from numba.core import types
    from numba.extending import overload

    @overload(select, jit_options=JIT_OPTIONS)
    def _select(condition, a, b):  # noqa: ANN001, ANN202 (numba typing hooks)
        if isinstance(condition, types.Array):
            return lambda condition, a, b: np.where(condition, a, b)
        return lambda condition, a, b: a if condition else b

    @overload(as_float, jit_options=JIT_OPTIONS)
    def _as_float(x):  # noqa: ANN001, ANN202
        if isinstance(x, types.Array):
            return lambda x: x.astype(np.float64)
        return lambda x: float(x)

    for target, fn in _JITABLE:
        _register_one(target, fn)
    _install_cache_locator()
    _registered = True


jitable(rss_row)


def _register_one(target: Callable, fn: Callable) -> None:
    from numba.extending import overload

    overload(target, jit_options=JIT_OPTIONS, strict=False)(lambda *args, **kwargs: fn)


def cache_sources() -> list[str]:
    """The modules whose source stamps the kernel's cache: every sumo_rss module that defines jitable or kernel
    functions, found in the package's files (not among the modules imported so far: the stamp must be the same in
    every process, whatever it imported; an audit imports none of the planner's, a test run all of them, and each
    recompiled what the other had cached)."""
    return [".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts) for path in _marked_files()]


def _marked_files() -> list[Path]:
    """The package's source files that define jitable, compiled_as or kernel functions, sorted."""
    marked = re.compile(r"^@(jitable|kernel|compiled_as)\b|^jitable\(", re.MULTILINE)
    return sorted(path for path in PACKAGE.rglob("*.py") if marked.search(path.read_text("utf-8")))


@functools.lru_cache(maxsize=1)
def _source_stamp() -> str:
    """A hash of the source of every :func:`cache_sources` module (what a cached kernel was compiled from)."""
    digest = hashlib.sha256()
    for path in _marked_files():
        digest.update(path.relative_to(PACKAGE.parent).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _install_cache_locator() -> None:
    """Put cache locators first in numba's list that stamp sumo_rss's cached functions with :func:`_source_stamp`
    (numba's own locators stamp a function with its own file's content hash only). Uses numba's locator classes
    and their list (``CacheImpl._locator_classes``), hence the pinned numba version (pyproject.toml)."""
    from numba.core import caching

    def hashed(base: type) -> type:
        class Hashed(base):
            @classmethod
            def from_function(cls, py_func, py_file):  # noqa: ANN001, ANN206
                if not Path(py_file).resolve().is_relative_to(PACKAGE.parent):  # the package, its tests, benches
                    return None
                return super().from_function(py_func, py_file)

            def get_source_stamp(self):  # noqa: ANN202
                return super().get_source_stamp(), _source_stamp()

        Hashed.__name__ = Hashed.__qualname__ = f"SumoRss{base.__name__}"
        return Hashed

    ours = [hashed(base) for base in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator,
                                      caching.UserWideCacheLocator)]
    caching.CacheImpl._locator_classes[:0] = ours
