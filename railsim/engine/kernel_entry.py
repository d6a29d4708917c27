"""A compiled kernel called without numba's per-call type dispatch, once the types of its arguments are fixed.

Calling a numba function from Python goes through its *dispatcher*: it works out the numba type of every argument,
finds the compiled version for those types, then calls that version's entry point, which unboxes the arguments
and runs the machine code. For the line step's 26 arguments the first part costs ~0.45 µs of a ~1.1 µs call,
every train and every step. When a caller always passes the same types, it may keep the entry point itself:

* :func:`direct` hands back the entry point of ``kernel`` compiled for ``signature`` — the types the kernel's
  module declares its callers pass — if the arguments of a call just made through the dispatcher had exactly
  those types; otherwise (other types, the kernel interpreted under ``NUMBA_DISABLE_JIT``, a numba without
  entry points) the dispatcher itself. A caller that gets the dispatcher is slower, never wrong.
* The entry point converts scalars as Python does (an ``int`` given for a float is that float), but it does **not**
  check an array's element type, dimensions or layout: it reads the memory as the signature says. Every array a
  caller hands it must therefore be made as the signature says; :func:`checked_array` says so where an array is
  made (once per array, not per call), and raises otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import typeof


def direct(kernel: Any, args: Sequence[Any], signature: tuple[Any, ...]) -> Callable[..., Any]:
    """The entry point of ``kernel`` compiled for ``signature`` if ``args`` (a call's arguments, already made
    through the dispatcher so the version exists) have exactly those types; else ``kernel``."""
    overloads = getattr(kernel, "overloads", None)
    if overloads is None or len(args) != len(signature):
        return kernel  # interpreted (NUMBA_DISABLE_JIT), or not a numba dispatcher
    if tuple(typeof(a) for a in args) != signature:
        return kernel
    compiled = overloads.get(signature)
    entry = getattr(compiled, "entry_point", None)
    return entry if callable(entry) else kernel


def checked_array(arr: np.ndarray, ndim: int) -> np.ndarray:
    """``arr`` if it is what the kernels' signatures declare for an array — float64, ``ndim`` dimensions,
    C-contiguous, aligned — which :func:`direct`'s entry points do not check; raise :class:`TypeError` if not."""
    if not (
        isinstance(arr, np.ndarray)
        and arr.dtype == np.float64
        and arr.ndim == ndim
        and arr.flags.c_contiguous
        and arr.flags.aligned
    ):
        raise TypeError(
            f"a compiled kernel's array must be float64, {ndim}-D, C-contiguous and aligned; got "
            f"{getattr(arr, 'dtype', type(arr).__name__)}, {getattr(arr, 'ndim', '?')}-D"
        )
    return arr
