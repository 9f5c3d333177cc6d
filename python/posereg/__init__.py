"""posereg from Python: register a labelled scan of a joint in one pose onto the same joint in
another, and get the warped scan, the displacement field, each bone's motion, the knee's
kinematics and the report, as the ``posereg register`` command writes them.

Images go in and come back either as numpy arrays in nibabel's convention (voxel axes x, y,
z; a 4×4 voxel → world RAS affine beside them) or as SimpleITK images (origin, spacing and
direction kept). Example::

    import nibabel as nib, posereg
    src, lab, tgt = (nib.load(p) for p in ("straight.nii.gz", "labels.nii.gz", "bent.nii.gz"))
    r = posereg.register(src.get_fdata(), lab.get_fdata(), tgt.get_fdata(),
                         source_affine=src.affine, target_affine=tgt.affine,
                         adaptive={"iterations": "40x30x20"})
    nib.save(nib.Nifti1Image(r.warped, r.target_affine), "warped.nii.gz")
    print(r.kinematics["joints"][0]["quantities"][0])   # tibiofemoral flexion
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from . import _posereg

__all__ = ["register", "Registration"]

# SimpleITK's world is LPS, posereg's (and nibabel's) RAS.
_LPS = np.diag([-1.0, -1.0, 1.0])


@dataclass
class Registration:
    """A registration's outputs, in the kind of image the target was given as.

    Arrays have voxel axes (x, y, z) and, for fields, a last axis of 3 vectors in LPS mm (the
    ITK/ANTs convention of ``field.nii.gz``: target point p → source point p + d).
    """

    #: The source resampled onto the target's grid through the field.
    warped: Any
    #: Target point → source point displacement, on the target's grid.
    field: Any
    #: Source point → target point displacement, on the source's grid.
    inverse_field: Any
    #: The field's Jacobian determinant on the target's grid.
    jacobian: Any
    #: transform.json's content: each bone's 4×4 motion (RAS, source → target) and more.
    transforms: dict
    #: kinematics.json's content, or None when the knee's kinematics could not be told.
    kinematics: Optional[dict]
    #: report.json's content: settings, per-bone confidence, correlation, folds, checks.
    report: dict
    #: The target's voxel → world RAS affine (the grid of warped, field, jacobian).
    target_affine: np.ndarray
    #: The source's voxel → world RAS affine (the grid of inverse_field).
    source_affine: np.ndarray


def _is_sitk(image) -> bool:
    return hasattr(image, "GetOrigin") and hasattr(image, "GetDirection")


def _from_sitk(image):
    """(array x,y,z, RAS affine) of a SimpleITK image."""
    import SimpleITK as sitk

    array = sitk.GetArrayFromImage(image).transpose(2, 1, 0)
    direction = np.array(image.GetDirection()).reshape(3, 3)
    affine = np.eye(4)
    affine[:3, :3] = _LPS @ direction @ np.diag(image.GetSpacing())
    affine[:3, 3] = _LPS @ np.array(image.GetOrigin())
    return array, affine


def _to_sitk(array, affine, vector=False):
    """A SimpleITK image of an (x, y, z[, 3]) array on the grid of a RAS affine."""
    import SimpleITK as sitk

    axes = (2, 1, 0, 3) if vector else (2, 1, 0)
    image = sitk.GetImageFromArray(np.ascontiguousarray(array.transpose(axes)), isVector=vector)
    linear = _LPS @ affine[:3, :3]
    spacing = np.linalg.norm(linear, axis=0)
    image.SetSpacing(spacing.tolist())
    image.SetDirection((linear / spacing).flatten().tolist())
    image.SetOrigin((_LPS @ affine[:3, 3]).tolist())
    return image


def _flat(image, affine, dtype, name):
    """(voxels x-fastest, dims, affine) of an array with its affine or a SimpleITK image."""
    if _is_sitk(image):
        array, affine = _from_sitk(image)
    elif hasattr(image, "affine") and hasattr(image, "get_fdata"):  # a nibabel image
        array, affine = np.asanyarray(image.dataobj), image.affine
    else:
        array = np.asarray(image)
        if affine is None:
            raise ValueError(f"{name}: an array needs its affine ({name}_affine=...)")
    array = np.asarray(array)
    if array.ndim != 3:
        raise ValueError(f"{name}: a 3-D image is needed, got shape {array.shape}")
    affine = np.asarray(affine, dtype=float)
    if affine.shape != (4, 4):
        raise ValueError(f"{name}: the affine must be 4×4, got {affine.shape}")
    if dtype is np.uint16:
        values = array.astype(np.float64)
        rounded = np.rint(values)
        if np.any(rounded != values) or rounded.min() < 0 or rounded.max() > 65535:
            raise ValueError(f"{name}: label codes must be whole numbers from 0 to 65535")
        array = rounded
    flat = np.ascontiguousarray(array.ravel(order="F").astype(dtype))
    return (flat, list(array.shape), affine.tolist()), array.shape, affine


def _shaped(flat, dims, vector=False):
    """An (x, y, z[, 3]) array from voxels x-fastest."""
    if vector:
        return flat.reshape(tuple(reversed(dims)) + (3,)).transpose(2, 1, 0, 3)
    return flat.reshape(tuple(reversed(dims))).transpose(2, 1, 0)


def _check_run_arguments(device, threads, progress):
    """The arguments that say how to run, checked before any work, each named when wrong."""
    if not isinstance(device, str):
        raise TypeError(f"device: a string (cpu, gpu or auto) is needed, got {type(device).__name__}")
    if device not in ("cpu", "gpu", "auto"):
        raise ValueError(f"device: {device!r} is not cpu, gpu or auto")
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)):
        raise TypeError(f"threads: a whole number is needed, got {type(threads).__name__}")
    if threads < 0:
        raise ValueError(f"threads: {threads} is below 0 (0 uses every core)")
    if not isinstance(progress, (bool, np.bool_)):
        raise TypeError(f"progress: True or False is needed, got {type(progress).__name__}")


def register(
    source,
    source_labels,
    target,
    *,
    source_affine=None,
    target_affine=None,
    device: str = "cpu",
    threads: int = 0,
    progress: bool = False,
    **settings: Any,
) -> Registration:
    """Registers ``source`` (the scan with bone labels ``source_labels``, on its grid) onto
    ``target``: per-bone rigid registration, the bones' motions blended across the soft tissue,
    then the adaptive non-rigid stage and the dense refinement (three levels by default;
    ``dense={"enabled": False}`` skips it).

    Each image is a SimpleITK image, a nibabel image, or a 3-D array with voxel axes (x, y, z)
    whose voxel → world RAS affine is given (``source_affine``, also used for the labels, and
    ``target_affine``); or all three are paths of NIfTI files, read and checked as ``posereg
    register`` reads them (the outputs are then arrays, on the grids ``target_affine`` and
    ``source_affine`` of the result give). ``settings`` are the settings a ``posereg register --config`` file
    holds, as keyword arguments of dicts: ``adaptive={"iterations": "40x30x20"}``,
    ``init={"blending": "linear"}``, ``initialise=False``. ``device``: "cpu", "gpu" or "auto";
    ``threads``: CPU threads (0: every core); ``progress``: stage lines on stderr. The GIL is
    released while it runs. Raises ValueError (a wrong value) or TypeError (a wrong kind of
    argument) naming the input, argument or setting that is wrong.
    """
    _check_run_arguments(device, threads, progress)
    paths = [isinstance(x, (str, os.PathLike)) for x in (source, source_labels, target)]
    if any(paths) and not all(paths):
        raise TypeError("source, source_labels and target: give all three as NIfTI paths, or "
                        "none (arrays with affines, nibabel or SimpleITK images)")
    if all(paths):
        files = [os.fspath(x) for x in (source, source_labels, target)]
        out = _posereg.register_files(*files, json.dumps(settings), device, threads, progress)
        (s_shape, s_affine), (t_shape, t_affine) = (
            (tuple(dims), np.array(affine)) for dims, affine in (out["source_grid"], out["target_grid"]))
    else:
        s, s_shape, s_affine = _flat(source, source_affine, np.float32, "source")
        l, _, _ = _flat(source_labels, source_affine, np.uint16, "source_labels")
        t, t_shape, t_affine = _flat(target, target_affine, np.float32, "target")
        out = _posereg.register_flat(s, l, t, json.dumps(settings), device, threads, progress)
    arrays = {
        "warped": _shaped(out["warped"], t_shape),
        "field": _shaped(out["field"], t_shape, vector=True),
        "inverse_field": _shaped(out["inverse_field"], s_shape, vector=True),
        "jacobian": _shaped(out["jacobian"], t_shape),
    }
    if _is_sitk(target):
        grids = {"inverse_field": s_affine}
        arrays = {
            k: _to_sitk(v, grids.get(k, t_affine), vector=v.ndim == 4) for k, v in arrays.items()
        }
    kinematics = out["kinematics"]
    return Registration(
        transforms=json.loads(out["transforms"]),
        kinematics=json.loads(kinematics) if kinematics else None,
        report=json.loads(out["report"]),
        target_affine=t_affine,
        source_affine=s_affine,
        **arrays,
    )
