"""Every file notchfit reads or writes, one module per kind of file (docs/data-formats.md).

=====================  ========================================================
module                 files
=====================  ========================================================
:mod:`.tables`         the CSV core: validated tables, column layouts
:mod:`.toml`           the TOML loader (errors name file and line), the writer
:mod:`.experiments`    experiment folders and studies, notch-point tables
:mod:`.camera`         camera files (YAML) and calibration-board definitions
:mod:`.images`         image files
:mod:`.models`         geometry files, friction-model parameters, FEA reference
:mod:`.outputs`        atomic writers, the output-run transaction, output files
:mod:`.resources`      where the shipped ``datasets/`` and ``calibration/`` are
=====================  ========================================================

Readers validate everything and raise an error naming the file, the line and
the problem; they never guess. Lengths are mm and tensions N in files, SI
(m, N, s) in memory; the conversion happens here. Writers are atomic.
Every public name of the submodules is importable from ``notchfit.io``.
"""

from .camera import load_board, read_camera, write_camera
from .experiments import (Experiment, attach_detections, is_experiment_dir, load_detected_points,
                          points_from_table, points_table, read_experiment, read_experiment_toml,
                          read_points_table, read_samples, read_study, with_points, write_experiment)
from .images import image_info, load_image
from .models import load_fea_reference, load_geometry, load_params, save_params
from .outputs import (STAGE_PREFIX, OutputRun, atomic_write, experiment_output_dir, find_output,
                      prepare_output_dir, provenance, read_detections, read_diagnosis, read_fits,
                      read_json, read_pointwise, read_simulation, write_json_atomic,
                      write_table_atomic, write_text_atomic)
from .resources import calibration_dir, datasets_dir
from .tables import (DETECTION_COLUMNS, FITS_COLUMNS, POINT_COLUMNS, POINTWISE_COLUMNS, SAMPLE_COLUMNS,
                     SIMULATION_COLUMNS, read_csv_table)
from .toml import TomlError, TomlFileNotFoundError, load_toml, toml_dumps

__all__ = [
    "DETECTION_COLUMNS",
    "Experiment",
    "FITS_COLUMNS",
    "OutputRun",
    "POINTWISE_COLUMNS",
    "POINT_COLUMNS",
    "SAMPLE_COLUMNS",
    "SIMULATION_COLUMNS",
    "STAGE_PREFIX",
    "TomlError",
    "TomlFileNotFoundError",
    "atomic_write",
    "attach_detections",
    "calibration_dir",
    "datasets_dir",
    "experiment_output_dir",
    "find_output",
    "image_info",
    "is_experiment_dir",
    "load_board",
    "load_detected_points",
    "load_fea_reference",
    "load_geometry",
    "load_image",
    "load_params",
    "load_toml",
    "points_from_table",
    "points_table",
    "prepare_output_dir",
    "provenance",
    "read_camera",
    "read_csv_table",
    "read_detections",
    "read_diagnosis",
    "read_experiment",
    "read_experiment_toml",
    "read_fits",
    "read_json",
    "read_points_table",
    "read_pointwise",
    "read_samples",
    "read_simulation",
    "read_study",
    "save_params",
    "toml_dumps",
    "with_points",
    "write_camera",
    "write_experiment",
    "write_json_atomic",
    "write_table_atomic",
    "write_text_atomic",
]
