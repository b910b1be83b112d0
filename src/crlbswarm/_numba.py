"""The decorator of the leaf kernels: compiled, cached, without reference counting.

Numba counts references to every array a compiled function receives, on entry and on exit,
with atomic instructions; in the mission's step these counts cost more than the arithmetic
(docs/performance.md, "Inside the mission kernel"). A kernel that allocates nothing needs no
counting: :func:`leaf` compiles it with Numba's ``_nrt=False`` (no runtime: allocating in
it is a compile error), so none is emitted.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba import njit

__all__ = ["leaf"]


def leaf(function: Callable[..., Any]) -> Any:
    """Compile ``function`` as a leaf kernel (cached; it must allocate nothing).

    Parameters
    ----------
    function : callable
        The Python function.

    Returns
    -------
    numba.core.registry.CPUDispatcher
        The compiled function.
    """
    return njit(cache=True, _nrt=False)(function)  # type: ignore[call-overload]
