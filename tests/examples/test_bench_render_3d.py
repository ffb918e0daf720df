"""benchmarks/bench_render_3d.py runs end to end in its smallest mode (no timing assertions),
writing its JSON into a temporary folder."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

_ROOT = Path(__file__).resolve().parents[2]
if (_ROOT / "benchmarks").is_dir() and str(_ROOT) not in sys.path:
    sys.path.insert(0, str(_ROOT))
benchmarks_common = pytest.importorskip("benchmarks._common")


def test_render_3d_benchmark_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from benchmarks import bench_render_3d

    monkeypatch.setattr(benchmarks_common, "RESULTS_DIR", tmp_path)
    rows = bench_render_3d.main(["--steps", "0", "--frames", "1", "--size", "16"])
    assert [row["triangles"] for row in rows] == [336, 4800]
    assert all(row["ms_per_frame"] > 0.0 and row["pixels"] == "768x480" for row in rows)
    assert (tmp_path / "render_3d.json").is_file()
