"""Writing results: field snapshots (npz, VTK, XDMF), extruded meshes (OBJ, PLY), probes (CSV,
PNG), checkpoints, and the output session that runs them between steps.

Every file is written atomically (a temporary file in the same folder, then ``os.replace``):
a reader, or a run stopped with Ctrl-C, never sees a partial file. Physics code never imports
this package.
"""

from elastoflow.io._atomic import atomic_path, write_bytes_atomic, write_text_atomic
from elastoflow.io._checkpoint import (
    CheckpointError,
    checkpoint_path,
    latest_checkpoint,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)
from elastoflow.io._fields import FIELD_FORMATS, FieldWriter, saved_frames, snapshot_arrays
from elastoflow.io._meshes import (
    boundary_edges_of,
    extrude_surface,
    write_extruded_meshes,
    write_obj,
    write_ply,
)
from elastoflow.io._probes import ProbeRecorder, plot_probes, read_probes
from elastoflow.io._session import (
    OutputSession,
    RangeTracker,
    apply_output_overrides,
    find_resume_checkpoint,
)

__all__ = [
    "FIELD_FORMATS",
    "CheckpointError",
    "FieldWriter",
    "OutputSession",
    "ProbeRecorder",
    "RangeTracker",
    "apply_output_overrides",
    "atomic_path",
    "boundary_edges_of",
    "checkpoint_path",
    "extrude_surface",
    "find_resume_checkpoint",
    "latest_checkpoint",
    "load_checkpoint",
    "plot_probes",
    "read_checkpoint",
    "read_probes",
    "save_checkpoint",
    "saved_frames",
    "snapshot_arrays",
    "write_bytes_atomic",
    "write_extruded_meshes",
    "write_obj",
    "write_ply",
    "write_text_atomic",
]
