"""Writing results: field snapshots (npz, VTK, XDMF; 3D fields as VTK image data), extruded
meshes (OBJ, PLY), probes (CSV, PNG), checkpoints, and the output session that runs them
between steps.

Every file is complete at any time: data files are written atomically (a temporary file in the
same folder, then ``os.replace``), the probes CSV and the XDMF series are streams extended by
single writes, the video is written in complete segments. A run killed at any point leaves
complete files, and a resumed run removes the temporaries and continues every output
(docs/reliability.md). Physics code never imports this package.
"""

from elastoflow.io._atomic import (
    atomic_path,
    remove_temporaries,
    write_bytes_atomic,
    write_text_atomic,
)
from elastoflow.io._checkpoint import (
    CheckpointError,
    checkpoint_path,
    checkpoints_by_step,
    latest_checkpoint,
    load_checkpoint,
    read_checkpoint,
    run_record,
    save_checkpoint,
)
from elastoflow.io._folder import OutputFolderBusy, folder_name, lock_output_folder
from elastoflow.io._image_data import (
    ImageData,
    ImageDataSeries,
    fluid_cell_fields_3d,
    read_image_data,
    write_image_data,
)
from elastoflow.io._fields import FIELD_FORMATS, FieldWriter, saved_frames, snapshot_arrays
from elastoflow.io._fields3d import FieldWriter3D
from elastoflow.io._meshes import (
    boundary_edges_of,
    extrude_polyline,
    extrude_surface,
    write_extruded_meshes,
    write_surface_meshes,
    write_obj,
    write_ply,
    write_tetrahedral_mesh,
)
from elastoflow.io._probes import ProbeRecorder, plot_probes, read_probes, write_rows_csv
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
    "FieldWriter3D",
    "ImageData",
    "ImageDataSeries",
    "OutputFolderBusy",
    "OutputSession",
    "ProbeRecorder",
    "RangeTracker",
    "apply_output_overrides",
    "atomic_path",
    "boundary_edges_of",
    "checkpoint_path",
    "checkpoints_by_step",
    "extrude_polyline",
    "extrude_surface",
    "find_resume_checkpoint",
    "fluid_cell_fields_3d",
    "folder_name",
    "latest_checkpoint",
    "load_checkpoint",
    "lock_output_folder",
    "plot_probes",
    "read_checkpoint",
    "read_image_data",
    "read_probes",
    "remove_temporaries",
    "run_record",
    "save_checkpoint",
    "saved_frames",
    "snapshot_arrays",
    "write_bytes_atomic",
    "write_extruded_meshes",
    "write_surface_meshes",
    "write_image_data",
    "write_obj",
    "write_rows_csv",
    "write_tetrahedral_mesh",
    "write_ply",
    "write_text_atomic",
]
