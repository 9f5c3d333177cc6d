"""Interoperability with the tools labs already use (run by tests/interop.rs).

Given a folder written by `posereg demo` (source, target, warped, field), this checks that
SimpleITK applies posereg's field.nii.gz (ITK displacement-field convention) to the source and
gets posereg's warped.nii.gz (correlation >= 0.999 inside the target's body), that SimpleITK
reads each bones/<name>.tfm as the transform the field applies to that bone, and that nibabel
reads every output with the target's affine.

    python3 tests/interop.py DIR
"""
import sys
from pathlib import Path

import nibabel as nib
import numpy as np
import SimpleITK as sitk

folder = Path(sys.argv[1])
source = sitk.ReadImage(str(folder / "source.nii.gz"), sitk.sitkFloat64)
target = sitk.ReadImage(str(folder / "target.nii.gz"), sitk.sitkFloat64)
field = sitk.ReadImage(str(folder / "field.nii.gz"), sitk.sitkVectorFloat64)
transform = sitk.DisplacementFieldTransform(field)
resampled = sitk.Resample(source, target, transform, sitk.sitkLinear, 0.0, sitk.sitkFloat64)

ours = sitk.GetArrayFromImage(sitk.ReadImage(str(folder / "warped.nii.gz"), sitk.sitkFloat64))
theirs = sitk.GetArrayFromImage(resampled)
body = sitk.GetArrayFromImage(target) > 0.05 * float(sitk.GetArrayFromImage(target).max())
r = np.corrcoef(ours[body], theirs[body])[0, 1]
print(f"SimpleITK resampling with posereg's field vs posereg's warped image: r = {r:.6f} "
      f"over {int(body.sum())} voxels, max |difference| {np.abs(ours - theirs)[body].max():.4f}")
assert r >= 0.999, f"correlation {r} < 0.999"

# Each bone's ITK transform (bones/<name>.tfm), read by SimpleITK, takes the bone's centroid
# where the field does: its inverse carries the source centroid into the target, and the field
# brings that target point back to the centroid.
import json
bones = {b["name"]: b["label"] for b in json.load(open(folder / "transform.json"))["bones"]}
labels = sitk.ReadImage(str(folder / "source_labels.nii.gz"))
label_array = sitk.GetArrayFromImage(labels)
assert bones, "transform.json has no bones"
for name, code in bones.items():
    tfm = sitk.ReadTransform(str(folder / "bones" / f"{name}.tfm"))
    index = np.argwhere(label_array == code)[:, ::-1].mean(0)
    centroid = labels.TransformContinuousIndexToPhysicalPoint(index.tolist())
    in_target = tfm.GetInverse().TransformPoint(centroid)
    back = transform.TransformPoint(in_target)
    gap = float(np.linalg.norm(np.subtract(back, centroid)))
    print(f"bones/{name}.tfm ({tfm.GetName()}): the field takes its centroid's target point "
          f"back within {gap:.3f} mm")
    assert gap < 0.5, f"{name}: {gap} mm"

reference = nib.load(str(folder / "target.nii.gz")).affine
for name in ["warped.nii.gz", "field.nii.gz"]:
    img = nib.load(str(folder / name))
    gap = np.abs(img.affine - reference).max()
    print(f"nibabel reads {name}: shape {img.shape}, affine differs from the target's by {gap:.2e}")
    assert gap < 1e-4, f"{name}: affine differs by {gap}"
print("interop ok")
