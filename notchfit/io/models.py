"""Model files: geometry TOML files, friction-model parameter files, the FEA reference values.

The physics modules hold the types and the pure mapping <-> object
conversions; this module reads and writes the files (docs/data-formats.md,
docs/geometry.md). Every TOML problem is a :class:`~notchfit.io.toml.TomlError`
naming the file and, where it can be found, the line.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..physics.friction_params import PARAM_KEYS, PER_JOINT_FIELDS, TUBE_FIELDS, FrictionParams
from ..physics.geometry import Geometry, geometry_from_dict
from ..physics.statics import FEAReference
from ..units import MM
from .outputs import write_text_atomic
from .resources import datasets_dir
from .toml import TomlError, load_toml, toml_dumps

__all__ = ["load_fea_reference", "load_geometry", "load_params", "params_from_mapping",
           "params_to_mapping", "save_params"]


_PARAMS_HEADER = ("# notchfit friction-model parameters (Sec. IV-B), SI units; "
                  "read by notchfit.io.load_params\n")


def load_geometry(source: str | os.PathLike | None = "default") -> Geometry:
    """Load a geometry from a TOML file (keys with unit suffixes, mm lengths; docs/geometry.md).

    Parameters
    ----------
    source : str or path, optional
        ``"default"`` (or None) for ``datasets/geometry/default.toml``, or a path.

    Returns
    -------
    Geometry

    Raises
    ------
    TomlError
        Naming the file, the key and (where it can be found) the line for a
        missing, unknown, non-numeric or non-positive field; a missing file
        is a :class:`~notchfit.io.toml.TomlFileNotFoundError`.
    """
    if source is None or str(source) == "default":
        path = datasets_dir() / "geometry" / "default.toml"
    else:
        path = Path(source)
    doc = load_toml(path, what="geometry file")
    try:
        return geometry_from_dict(doc.data, origin=str(path), line_of=doc.line_of)
    except ValueError as exc:
        raise doc.locate(str(exc)) from None
    except (TypeError, OverflowError, ArithmeticError, KeyError, IndexError) as exc:
        # geometry_from_dict checks types and signs; what it lets through fails later in Geometry
        raise TomlError(f"{path}: invalid geometry ({type(exc).__name__}: {exc}); see docs/geometry.md",
                        path=path) from None


def load_params(path) -> FrictionParams:
    """Friction parameters from a TOML file (keys with units, :data:`notchfit.physics.friction_params.PARAM_KEYS`).

    Missing keys take the paper's values; a ``[metadata]`` table is ignored.
    Plain field names (``k_lin``) are accepted too.

    Raises
    ------
    TomlError
        Naming the file and the key for an unknown key, a non-number or an
        invalid value; a syntax error with its line; a missing file is a
        :class:`~notchfit.io.toml.TomlFileNotFoundError`.
    """
    doc = load_toml(path, what="friction parameter file")
    _check_magnitudes(doc)
    try:
        return params_from_mapping(doc.data, origin=str(doc.path))
    except ValueError as exc:
        raise doc.locate(str(exc)) from None
    except (TypeError, OverflowError, ArithmeticError) as exc:     # e.g. an integer too large for a float
        raise TomlError(f"{doc.path}: invalid friction parameters ({type(exc).__name__}: {exc})",
                        path=doc.path) from None


#: Largest magnitude of a model-file number [SI]; moduli (keys ending in ``_Pa``, fields ``E_...``)
#: go up to :data:`MODULUS_MAX_PA`, and a time constant (``_s``) may not be below
#: :data:`TIME_MIN_S` unless 0. Beyond them a value is a typo or a unit mistake, and the simulator
#: crawls through it in one uninterruptible kernel call (measured: a tip force of 1e6 N ran for
#: minutes, 1e4 N for 16 s; damping_time_s = 1e-30 for 36 s, 1e-15 for 0.4 s).
MODEL_MAX = 1e3
MODULUS_MAX_PA = 1e13
TIME_MIN_S = 1e-12


def _magnitude_problem(key: str, v) -> str | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None                 # the types are checked by the model
    a = abs(float(v)) if abs(v) < 1e308 else math.inf
    top = MODULUS_MAX_PA if (key.endswith("_Pa") or key.startswith("E_")) else MODEL_MAX
    low = TIME_MIN_S if key.endswith("_s") and not key.endswith("_per_s") else 0.0
    if math.isfinite(a) and (a > top or 0 < a < low):
        rng = f"0 or {low:g} to {top:g}" if low else f"at most {top:g} in magnitude"
        return f"{key} = {v!r} is an absurd value (accepted: {rng}, in the key's SI unit)"
    return None


def _check_magnitudes(doc) -> None:
    """Refuse absurd magnitudes in a model file (types, signs and finiteness are the model's checks)."""
    for key, val in doc.data.items():
        if key == "metadata":
            continue
        for v in (val if isinstance(val, list) else [val]):
            problem = _magnitude_problem(str(key), v)
            if problem:
                raise doc.error(problem, key)


def save_params(params: FrictionParams, path, **metadata) -> Path:
    """Write ``params`` as TOML (SI keys with units) plus a ``[metadata]`` table.

    Floats are written with ``repr`` (exact round trip through :func:`load_params`).
    Metadata values: numbers (NaN allowed), strings, booleans, lists of those, or
    nested dicts (written as ``[metadata.name]`` tables). The file is written
    atomically: an old file is either kept whole or replaced whole.

    Returns
    -------
    Path
    """
    data = params_to_mapping(params)
    if metadata:
        data["metadata"] = metadata
    return write_text_atomic(_PARAMS_HEADER + toml_dumps(data), Path(path))


def load_fea_reference(path: str | os.PathLike | None = None) -> FEAReference:
    """The paper's FEA of a 4-joint segment (Sec. III-D, Fig. 10), SI units.

    Parameters
    ----------
    path : str or path, optional
        Default: ``datasets/reference/fea_sec3d.toml``.

    Raises
    ------
    TomlError
        A missing key, or joint-angle lists whose length is not ``n_joints``.
    """
    path = Path(path) if path is not None else datasets_dir() / "reference" / "fea_sec3d.toml"
    doc = load_toml(path, what="FEA reference file")
    d = doc.data
    try:
        out = FEAReference(
            n_joints=int(d["n_joints"]), E=float(d["E_Pa"]), nu=float(d["poisson_ratio"]),
            moment=float(d["moment"]["moment_Nm"]),
            theta_moment=np.asarray(d["moment"]["theta_rad"], dtype=float),
            transverse_force=float(d["transverse"]["force_N"]),
            theta_transverse=np.asarray(d["transverse"]["theta_rad"], dtype=float),
            axial_force=float(d["axial"]["force_N"]),
            axial_max_displacement=float(d["axial"]["max_displacement_mm"]) * MM,
            source=str(d.get("source", "")))
    except KeyError as exc:
        raise doc.error(f"missing key {exc}") from None
    except (TypeError, ValueError, OverflowError) as exc:
        raise doc.error(f"invalid value ({exc})") from None
    for table, a in (("moment", out.theta_moment), ("transverse", out.theta_transverse)):
        if a.shape != (out.n_joints,):
            raise doc.error(f"joint-angle lists must have n_joints={out.n_joints} entries", table, "theta_rad")
    return out


# =============================================================================
# the model.toml mapping (file keys with units <-> FrictionParams fields)
# =============================================================================
def params_from_mapping(data: dict, origin: str = "<dict>") -> FrictionParams:
    """Friction parameters from a parameter-file mapping (keys with units, :data:`notchfit.physics.friction_params.PARAM_KEYS`).

    Parameters
    ----------
    data : dict
        Missing keys take the paper's values; a ``metadata`` table is ignored.
        Plain field names (``k_lin``) are accepted too.
    origin : str
        Where the mapping came from, at the start of every message.

    Returns
    -------
    FrictionParams

    Raises
    ------
    ValueError
        ``"<origin>: <problem>"`` for an unknown key, a key given twice, a
        non-number or an invalid value.
    """
    by_key = {v: k for k, v in PARAM_KEYS.items()}
    kw = {}
    for key, val in data.items():
        if key == "metadata" and isinstance(val, dict):
            continue
        field = by_key.get(key, key if key in PARAM_KEYS else None)
        if field is None:
            raise ValueError(f"{origin}: unknown friction parameter {key!r} "
                             f"(known: {', '.join(PARAM_KEYS.values())})")
        if field in kw:
            raise ValueError(f"{origin}: parameter {field} given twice")
        kw[field] = _mapping_value(field, key, val, origin)
    try:
        return FrictionParams(**kw)
    except ValueError as exc:
        raise ValueError(f"{origin}: {exc}") from None


def _mapping_value(field: str, key: str, val, origin: str):
    """One parameter-file value: a string law, a number, or a list for a per-joint field."""
    if field in ("spring_law", "friction_law"):
        if not isinstance(val, str):
            raise ValueError(f"{origin}: {key} must be a string, got {val!r}")
        return val
    if field in PER_JOINT_FIELDS + TUBE_FIELDS and isinstance(val, list):
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in val):
            raise ValueError(f"{origin}: {key} must be a number or a list of numbers, got {val!r}")
        return tuple(float(v) for v in val)
    if isinstance(val, bool) or not isinstance(val, (int, float)):
        raise ValueError(f"{origin}: {key} must be a number, got {val!r}")
    return float(val)


def params_to_mapping(params: FrictionParams) -> dict:
    """``{file key: value}`` of ``params`` (SI keys with units, :data:`notchfit.physics.friction_params.PARAM_KEYS`), in file order.

    The seed model's keys always; the real-tube keys (laws, damping time,
    material) only where they differ from their defaults, so a seed model file
    is as before. Per-joint values are lists.
    """
    return {PARAM_KEYS[f]: v for f, v in params.to_dict().items()}
