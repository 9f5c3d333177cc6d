"""Interoperability with the tools labs already use (run by tests/interop.rs).

Given a folder written by `posereg demo` (source, target, warped, field), this checks that
SimpleITK applies posereg's field.nii.gz (ITK displacement-field convention) to the source and
gets posereg's warped.nii.gz (correlation >= 0.999 inside the target's body), and that nibabel
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

reference = nib.load(str(folder / "target.nii.gz")).affine
for name in ["warped.nii.gz", "field.nii.gz"]:
    img = nib.load(str(folder / name))
    gap = np.abs(img.affine - reference).max()
    print(f"nibabel reads {name}: shape {img.shape}, affine differs from the target's by {gap:.2e}")
    assert gap < 1e-4, f"{name}: affine differs by {gap}"
print("interop ok")
