"""What a damaged checkpoint is called: NumPy reports any file that is neither a zip nor an
.npy as 'pickled data', and the message said "it holds pickled Python objects" of a text file."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from elastoflow.io import CheckpointError, read_checkpoint


def test_a_text_file_is_not_called_a_pickle(tmp_path: Path) -> None:
    path = tmp_path / "checkpoint_00000010.npz"
    path.write_text("hello\n")
    with pytest.raises(CheckpointError, match=r"not a NumPy \.npz file: it starts with "
                                              r"b'hello\\n'") as caught:
        read_checkpoint(path)
    assert "pickled" not in str(caught.value)


def test_a_pickle_is_called_a_pickle(tmp_path: Path) -> None:
    path = tmp_path / "checkpoint_00000010.npz"
    path.write_bytes(pickle.dumps({"time": 1.0}))
    with pytest.raises(CheckpointError, match="holds pickled Python objects") as caught:
        read_checkpoint(path)
    assert "allow_pickle" not in str(caught.value)
