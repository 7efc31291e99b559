"""Finding MKL's runtime for pypardiso without its recursive search of the venv."""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

import pytest

from fe.linalg import sparse


def test_points_pypardiso_at_a_loadable_mkl_in_the_prefix(monkeypatch):
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    libs = sorted(Path(sys.prefix, "lib").glob("libmkl_rt.so*"))
    if not libs:
        pytest.skip(f"no libmkl_rt.so* in {sys.prefix}/lib (MKL not installed by pip here)")
    sparse._point_pypardiso_at_mkl()

    path = os.environ["PYPARDISO_MKL_RT"]
    assert Path(path) in libs
    ctypes.CDLL(path)  # loadable


def test_leaves_the_search_to_pypardiso_without_a_loadable_lib(monkeypatch, tmp_path):
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "libmkl_rt.so.9").write_bytes(b"not a library")
    monkeypatch.setattr(sys, "prefix", str(tmp_path))
    sparse._point_pypardiso_at_mkl()

    assert "PYPARDISO_MKL_RT" not in os.environ


def test_keeps_a_users_choice(monkeypatch):
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/somewhere/libmkl_rt.so")
    sparse._point_pypardiso_at_mkl()

    assert os.environ["PYPARDISO_MKL_RT"] == "/somewhere/libmkl_rt.so"
