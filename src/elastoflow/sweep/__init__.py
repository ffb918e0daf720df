"""Parameter sweeps and ensembles: many runs of one scene with parameters varied by key path,
run on Dask (distributed): a local cluster, an existing scheduler, or a SLURM/PBS cluster
through dask-jobqueue (docs/sweeps.md).

``elastoflow sweep SWEEP.toml`` is the command; in Python::

    plan = plan_sweep(load_sweep("sweep.toml"))
    with open_client() as client:
        outcome = run_sweep(plan, Path("out/sweep"), client)
    pandas.read_parquet(outcome.summary)
"""

from elastoflow.sweep._engine import (
    SweepOutcome,
    SweepProgress,
    local_worker_count,
    open_client,
    prepare_folder,
    run_sweep,
)
from elastoflow.sweep._plan import SweepPlan, SweepPoint, plan_sweep, set_key_path
from elastoflow.sweep._results import STATUSES, read_result, scalar_results, summary_frame
from elastoflow.sweep._spec import SNAPSHOT_FIELDS, SweepError, SweepSpec, load_sweep, parse_sweep
from elastoflow.sweep._worker import PointTask, run_point

__all__ = [
    "SNAPSHOT_FIELDS",
    "STATUSES",
    "PointTask",
    "SweepError",
    "SweepOutcome",
    "SweepPlan",
    "SweepPoint",
    "SweepProgress",
    "SweepSpec",
    "load_sweep",
    "local_worker_count",
    "open_client",
    "parse_sweep",
    "plan_sweep",
    "prepare_folder",
    "read_result",
    "run_point",
    "run_sweep",
    "scalar_results",
    "set_key_path",
    "summary_frame",
]
