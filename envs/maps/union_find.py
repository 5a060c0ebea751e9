"""Union-find over flat cell indices, for compiled kernels that join cells into parts."""

from __future__ import annotations

from envs.kernel_cache import njit


@njit(cache=True, nogil=True)
def find_root(parent, a):
    """The root of cell ``a``'s part in the forest ``parent`` ((N,) ints, a root its own parent),
    halving the path on the way (each visited cell then points to its grandparent)."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


__all__ = ["find_root"]
