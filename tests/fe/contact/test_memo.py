"""fe.contact.memo: values kept per live array, by identity, dropped with the array."""

import gc
import threading

import numpy as np

from fe.contact.memo import ArrayMemo, start_afresh
from fe.contact.state import _FINGERPRINTS, fingerprint, is_symmetric


def test_value_is_kept_for_the_same_array_only():
    memo: ArrayMemo[str] = ArrayMemo()
    a, b = np.zeros(3), np.zeros(3)
    memo.put(a, "a")
    assert memo.get(a) == "a"
    assert memo.get(b) is None  # equal contents, another array
    assert memo.get(a[:2]) is None  # a view is another array
    memo.put(a, "again")
    assert memo.get(a) == "again"
    assert len(memo) == 1


def test_entry_dies_with_its_array():
    memo: ArrayMemo[int] = ArrayMemo()
    a = np.ones(4)
    memo.put(a, 1)
    del a
    gc.collect()
    assert len(memo) == 0


def test_late_callback_of_a_replaced_array_keeps_the_new_entry():
    """A dying array's callback drops its own entry only, not a newer one under its key."""
    memo: ArrayMemo[int] = ArrayMemo()
    a = np.ones(4)
    memo.put(a, 1)
    key = memo._key(a)
    old_ref = memo._entries[key][0]
    memo.put(a, 2)  # a newer entry under the same key (as for a new array with a's id)
    memo._drop(key, old_ref)
    assert memo.get(a) == 2
    memo._drop(key, memo._entries[key][0])
    assert memo.get(a) is None


def test_per_thread_values_are_separate():
    memo: ArrayMemo[str] = ArrayMemo(per_thread=True)
    a = np.zeros(2)
    memo.put(a, "main")
    seen: list[str | None] = []
    worker = threading.Thread(target=lambda: seen.append(memo.get(a)))
    worker.start()
    worker.join()
    assert seen == [None]
    assert memo.setdefault(a, lambda: "other") == "main"


def test_fingerprint_is_remembered_only_for_a_frozen_array():
    W = np.arange(9.0).reshape(3, 3).copy()  # owns its data
    assert fingerprint(W) == 36.0
    W[0, 0] = 100.0  # writeable: summed again
    assert fingerprint(W) == 136.0
    assert _FINGERPRINTS.get(W) is None
    W.setflags(write=False)
    assert fingerprint(W) == 136.0
    assert _FINGERPRINTS.get(W) == 136.0


def test_symmetry_is_checked_again_when_the_fingerprint_changes():
    W = np.eye(3)
    assert is_symmetric(W, float(W.sum()))
    W[0, 1] = 1.0  # changed in place: a new fingerprint must give a new answer
    assert not is_symmetric(W, float(W.sum()))
    W[0, 1] = 0.0
    W[2, 0] = 5.0
    assert not is_symmetric(W, float("nan"))  # unknown fingerprint: never reused


def test_pop_forgets_the_value_of_that_array_only():
    memo: ArrayMemo[str] = ArrayMemo()
    a, b = np.zeros(2), np.zeros(2)
    memo.put(a, "a")
    memo.put(b, "b")
    assert memo.pop(np.zeros(2)) is None  # equal contents, another array
    assert memo.pop(a) == "a"
    assert memo.get(a) is None
    assert memo.pop(a) is None
    assert memo.get(b) == "b"
    assert len(memo) == 1


def test_a_fresh_start_forgets_what_this_thread_learnt_and_nothing_else():
    learned: ArrayMemo[str] = ArrayMemo(per_thread=True, learned=True)
    content: ArrayMemo[str] = ArrayMemo()  # a property of W's content (symmetry, sum)
    a = np.zeros(2)
    learned.put(a, "this thread")
    content.put(a, "symmetric")
    other: list[str | None] = []

    def elsewhere() -> None:
        learned.put(a, "other thread")
        barrier.wait()  # this thread starts afresh meanwhile
        barrier.wait()
        other.append(learned.get(a))

    barrier = threading.Barrier(2)
    worker = threading.Thread(target=elsewhere)
    worker.start()
    barrier.wait()
    start_afresh()
    barrier.wait()
    worker.join()

    assert learned.get(a) is None
    assert content.get(a) == "symmetric"
    assert other == ["other thread"]  # a cycle running in another thread keeps its own


def test_a_learned_memo_must_be_per_thread():
    import pytest

    with pytest.raises(ValueError, match="per_thread"):
        ArrayMemo(learned=True)
