"""Interoperability with the tools labs already use (run by tests/interop.rs).

Given a folder written by `posereg demo` (source, target, warped, field, bones/) with
target_on_source.nii.gz added by `posereg apply --inverse`, this checks that
- SimpleITK and ANTs (antspyx `apply_transforms`) apply posereg's field.nii.gz (ITK
  displacement-field convention) to the source and get posereg's warped.nii.gz (correlation
  >= 0.999 inside the target's body);
- SimpleITK and ANTs read each bones/<name>.tfm as the motion the field gives that bone: the
  source labels resampled through the .tfm and through the field agree (Dice >= 0.99 per bone);
- ANTs inverts bones/<name>.mat (`whichtoinvert`) and brings the target back onto the source
  as posereg's inverse field does, inside each bone (correlation >= 0.99);
- nibabel reads every output with the target's affine.

    python3 tests/interop.py DIR
"""
import sys
from pathlib import Path

import ants
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


def dice(a, b):
    return 2.0 * np.logical_and(a, b).sum() / max(a.sum() + b.sum(), 1)


# The source labels carried into the target by each bone's .tfm (SimpleITK and ANTs) against
# the field, bone by bone.
through_field = sitk.GetArrayFromImage(
    sitk.Resample(labels, target, transform, sitk.sitkNearestNeighbor, 0))
ants_target = ants.image_read(str(folder / "target.nii.gz"))
ants_labels = ants.image_read(str(folder / "source_labels.nii.gz"))
ants_source = ants.image_read(str(folder / "source.nii.gz"))
ants_warped = ants.apply_transforms(fixed=ants_target, moving=ants_source,
                                    transformlist=[str(folder / "field.nii.gz")])
r = np.corrcoef(ants_warped.numpy()[body.T], ours.T[body.T])[0, 1]
print(f"ANTs apply_transforms with posereg's field vs posereg's warped image: r = {r:.6f}")
assert r >= 0.999, f"ANTs: correlation {r} < 0.999"
back = ants.image_read(str(folder / "target_on_source.nii.gz")).numpy()
for name, code in bones.items():
    tfm = str(folder / "bones" / f"{name}.tfm")
    by_sitk = sitk.GetArrayFromImage(sitk.Resample(
        labels, target, sitk.ReadTransform(tfm), sitk.sitkNearestNeighbor, 0))
    by_ants = ants.apply_transforms(fixed=ants_target, moving=ants_labels, transformlist=[tfm],
                                    interpolator="nearestNeighbor").numpy()
    d_sitk = dice(by_sitk == code, through_field == code)
    d_ants = dice(by_ants == code, through_field.T == code)
    inverse = ants.apply_transforms(fixed=ants_source, moving=ants_target,
                                    transformlist=[str(folder / "bones" / f"{name}.mat")],
                                    whichtoinvert=[True]).numpy()
    bone = ants_labels.numpy() == code
    r_back = np.corrcoef(inverse[bone], back[bone])[0, 1]
    print(f"bones/{name}: Dice with the field's labels {d_sitk:.4f} (SimpleITK, .tfm), "
          f"{d_ants:.4f} (ANTs, .tfm); target brought back by ANTs through the inverted .mat vs "
          f"posereg's inverse field, inside the bone: r = {r_back:.5f}")
    assert d_sitk >= 0.99 and d_ants >= 0.99, f"{name}: Dice {d_sitk}, {d_ants}"
    assert r_back >= 0.99, f"{name}: r = {r_back}"

reference = nib.load(str(folder / "target.nii.gz")).affine
for name in ["warped.nii.gz", "field.nii.gz", "jacobian.nii.gz"]:
    img = nib.load(str(folder / name))
    gap = np.abs(img.affine - reference).max()
    print(f"nibabel reads {name}: shape {img.shape}, affine differs from the target's by {gap:.2e}")
    assert gap < 1e-4, f"{name}: affine differs by {gap}"
print("interop ok")
