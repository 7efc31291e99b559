"""Values remembered per live array: the caches of :mod:`fe.contact` keyed by ``W``.

Internal to :mod:`fe.contact`. The contact solver sees the same Delassus operator ``W``
at every increment of a cycle and keeps what it learnt of it (its sum, whether it is
symmetric, a preconditioner, a working-set block) until the array dies. Keying by
``id(W)`` alone is unsafe (an id is reused once its array is freed), so every entry
holds a weak reference that must still point to the array asked about, and the entry
is dropped when the array dies. Whether ``W`` changed in place is the caller's concern
(the fingerprint ``Problem.w_sum`` stored with the value).

Example:
    >>> import numpy as np
    >>> memo: ArrayMemo[float] = ArrayMemo()
    >>> W = np.eye(3)
    >>> memo.put(W, 3.0)
    >>> memo.get(W), memo.get(np.eye(3)), len(memo)
    (3.0, None, 1)
    >>> del W
    >>> len(memo)
    0
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Callable
from typing import Any, Generic, TypeVar

import numpy as np

V = TypeVar("V")


_LEARNED: list[ArrayMemo[Any]] = []
"""The memos whose values a solve learns along a cycle (``learned=True``)."""


def start_afresh() -> None:
    """Forget what this thread's solves learnt of every ``W`` (call at the start of a cycle).

    A cycle that reuses an earlier cycle's ``W`` (the condensed configurations of a
    geometry are kept for every amplitude and candidate) would otherwise start from the
    Krylov base LU and the working set that cycle left: another Newton path, so other
    bits and another iteration count (measured: one coarse cycle 120 against 124
    iterations, loops 1e-10 apart), and a cycle's numbers would depend on which cycles
    ran before it in the process, e.g. in process against on a Dask worker (issue 35).
    What depends on ``W``'s content only (its fingerprint, its symmetry) is kept.
    """
    ident = threading.get_ident()
    for memo in _LEARNED:
        memo._forget_thread(ident)


class ArrayMemo(Generic[V]):
    """One value per live array (and per thread if ``per_thread``), thread-safe.

    Args:
        per_thread: Keep a separate value for every thread (for mutable values such as a
            preconditioner workspace that two threads must not share).
        learned: The values are learnt along a cycle and forgotten by
            :func:`start_afresh` (needs ``per_thread``).
    """

    def __init__(self, per_thread: bool = False, *, learned: bool = False) -> None:
        if learned and not per_thread:
            raise ValueError("a learned memo must be per_thread (start_afresh is per thread)")
        self._per_thread = per_thread
        self._entries: dict[tuple[int, int], tuple[weakref.ref[np.ndarray], V]] = {}
        # Reentrant: a collection run while the lock is held may drop another entry.
        self._lock = threading.RLock()
        if learned:
            _LEARNED.append(self)

    def _forget_thread(self, ident: int) -> None:
        with self._lock:
            for key in [k for k in self._entries if k[1] == ident]:
                del self._entries[key]

    def _key(self, a: np.ndarray) -> tuple[int, int]:
        return (id(a), threading.get_ident() if self._per_thread else 0)

    def get(self, a: np.ndarray) -> V | None:
        """The value kept for ``a`` (None if there is none)."""
        with self._lock:
            entry = self._entries.get(self._key(a))
        if entry is None or entry[0]() is not a:
            return None
        return entry[1]

    def put(self, a: np.ndarray, value: V) -> None:
        """Keep ``value`` for ``a`` (replacing any earlier one) while ``a`` lives."""
        key = self._key(a)
        entry = (weakref.ref(a, lambda r: self._drop(key, r)), value)  # made outside the lock
        with self._lock:
            self._entries[key] = entry

    def pop(self, a: np.ndarray) -> V | None:
        """Forget the value kept for ``a`` and return it (None if there is none)."""
        key = self._key(a)
        with self._lock:
            entry = self._entries.get(key)
            if entry is None or entry[0]() is not a:
                return None
            del self._entries[key]
        return entry[1]

    def setdefault(self, a: np.ndarray, make: Callable[[], V]) -> V:
        """The value kept for ``a``, made by ``make()`` and kept if there is none.

        Not atomic: two threads asking at once for a shared (not ``per_thread``) key may
        both make a value, and the last one is kept.
        """
        value = self.get(a)
        if value is None:
            value = make()
            self.put(a, value)
        return value

    def _drop(self, key: tuple[int, int], ref: weakref.ref[np.ndarray]) -> None:
        # Only the entry of the array that died: a new array may already reuse its id.
        with self._lock:
            entry = self._entries.get(key)
            if entry is not None and entry[0] is ref:
                del self._entries[key]

    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)
