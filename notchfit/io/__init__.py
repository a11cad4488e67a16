"""Every file notchfit reads or writes, one module per kind of file (docs/data-formats.md).

=====================  ========================================================
module                 files
=====================  ========================================================
:mod:`.errors`         the one reader error type, file and text checks
:mod:`.interrupts`     Ctrl-C/SIGTERM as an exception; sections they cannot cut
:mod:`.tables`         the CSV core: validated tables, column layouts
:mod:`.toml`           the TOML loader (errors name file and line), the writer
:mod:`.experiments`    experiment folders (``experiment.toml``) and studies
:mod:`.measurements`   an experiment's tables: samples, notch points, joint angles
:mod:`.camera`         camera files (YAML) and calibration-board definitions
:mod:`.images`         image files
:mod:`.models`         geometry files, friction-model parameters, FEA reference
:mod:`.outputs`        atomic writers, the output-run transaction, output files
:mod:`.results`        typed readers of result files (diagnosis.json, identify.json, run records, tables)
:mod:`.resume`         resumable output runs: finished items kept, a stopped run continued
:mod:`.resources`      where the shipped ``datasets/`` and ``calibration/`` are
:mod:`.review`         ``review.csv``: a person's corrections of a detect run
=====================  ========================================================

Readers validate everything and raise an :class:`InputFileError` (a
``ValueError``; a missing file is an :class:`InputFileNotFoundError`, also a
``FileNotFoundError``) naming the file, the line and the problem, in one
line; they never guess (docs/reliability.md). Lengths are mm and tensions N in files, SI
(m, N, s) in memory; the conversion happens here. Writers are atomic.
Every public name of the submodules is importable from ``notchfit.io``.
"""

import importlib

#: Where each public name lives. The submodules are imported on first use (PEP 562), so that
#: the command line's error and interrupt handling (:mod:`.errors`, :mod:`.interrupts`) loads
#: neither pandas nor OpenCV, and `notchfit --help` stays fast.
_HOME = {
    "camera": ("load_board", "read_camera", "write_camera"),
    "errors": ("InputFileError", "InputFileNotFoundError"),
    "experiments": ("Experiment", "PointsLookup", "StudyScan", "find_points", "has_own_points",
                    "is_experiment_dir", "load_detected_points", "read_experiment", "read_experiment_toml",
                    "read_study", "scan_study", "with_points", "write_experiment"),
    "measurements": ("ANGLE_COLUMNS", "angles_from_table", "angles_table", "points_from_table", "points_table",
                     "read_angles_table", "read_points_table", "read_samples"),
    "images": ("EXIF_ORIENTATIONS", "PNG_SETTINGS", "encode_image", "exif_orientation", "image_info",
               "image_orientation", "load_image", "orient", "write_image"),
    "models": ("load_fea_reference", "load_geometry", "load_params", "params_from_mapping", "params_to_mapping",
               "save_params"),
    "outputs": ("LOCK_NAME", "STAGE_PREFIX", "OutputLockedError", "OutputRun", "atomic_write",
                "existing_outputs", "experiment_output_dir", "find_output", "live_lock_holder", "prepare_output_dir", "provenance", "read_detections",
                "read_diagnosis", "read_fits", "read_json", "read_pointwise", "read_simulation",
                "write_json_atomic", "write_table_atomic", "write_text_atomic"),
    "resources": ("calibration_dir", "datasets_dir"),
    "results": ("DiagnosisRecord", "IdentifyRecord", "RunRecord", "read_angle_fits", "read_diagnosis_csv",
                "read_diagnosis_record", "read_identify", "read_run_records", "read_simulation_vs_measured"),
    "review": ("REVIEW_COLUMNS", "REVIEW_NAME", "REVIEW_STATUSES", "apply_review", "read_review", "review_path",
               "write_review"),
    "resume": ("ContentHash", "NothingToResumeError", "RESUME_PREFIX", "ResumableRun", "check_resumable",
               "file_sha256", "options_sha256",
               "write_bytes_synced"),
    "tables": ("DETECTION_COLUMNS", "FITS_COLUMNS", "POINT_COLUMNS", "POINTWISE_COLUMNS", "SAMPLE_COLUMNS",
               "SIMULATION_COLUMNS", "read_csv_table"),
    "toml": ("TomlError", "TomlFileNotFoundError", "load_toml", "toml_dumps"),
}
_WHERE = {name: mod for mod, names in _HOME.items() for name in names}


def __getattr__(name):
    """A public name of a submodule, imported on first use."""
    mod = _WHERE.get(name)
    if mod is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{mod}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))


__all__ = sorted(_WHERE)
