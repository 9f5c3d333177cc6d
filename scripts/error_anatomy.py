#!/usr/bin/env python3
"""Where and why a registration of a make_pair.py pair misses its truth, independently of posereg.

    scripts/error_anatomy.py PAIR_DIR FIELD [FIELD ...]

For the pair's own truth and each FIELD (ITK convention, on the target grid, as
scripts/score_pair.py reads it), over the pair's soft tissue:
- image match: local correlation (squared, as LNCC costs count it) of the target with the source
  warped through the field, in cubic windows of radius 1, 2 and 4 voxels. A field that matches
  worse than the truth stopped short of it; one that matches better fitted the noise;
- volume: the share of the soft tissue the field keeps within 0.8-1.25x its volume (det J) and
  the mean |log det J|;
- for each FIELD, the error against the truth: mean, and the part left after smoothing the error
  field with Gaussians of 6, 12 and 24 mm (how much of it is of middle or large scale); and the
  error split by d1 + d2, the distances (mm) to the nearest two bones of the target's labels
  (the bones truth.json lists; below 20 mm: the gaps between bones, where posereg's dense
  velocity, held at zero on the bones and rising over a few mm, is smallest), each bin's mean
  and its share of the summed error.
Shares nothing with the registration (numpy, scipy, SimpleITK); BENCHMARKS.md, thirty-seventh
session, reports what it printed for the knee pairs.
"""
import json
import os
import sys

import numpy as np
import scipy.ndimage as nd
import SimpleITK as sitk

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from score_pair import KEPT_VOLUME, jacobian_determinant, read_field, resampled  # noqa: E402

RADII = (1, 2, 4)
SMOOTHING_MM = (6, 12, 24)


def lncc(a, b, radius):
    """Squared correlation of a and b in (2 radius + 1)³ windows, per voxel."""
    mean = lambda x: nd.uniform_filter(x, 2 * radius + 1)  # noqa: E731
    ma, mb = mean(a), mean(b)
    va, vb, cab = mean(a * a) - ma**2, mean(b * b) - mb**2, mean(a * b) - ma * mb
    return np.clip(cab**2 / np.maximum(va * vb, 1e-12), 0.0, 1.0)


def image_and_volume(name, field, scans, soft):
    source, target = scans
    fixed, moved = sitk.GetArrayFromImage(target), resampled(source, field)
    match = " / ".join(f"{lncc(fixed, moved, r)[soft].mean():.3f}" for r in RADII)
    det = jacobian_determinant(field)[soft]
    kept = ((det >= KEPT_VOLUME[0]) & (det <= KEPT_VOLUME[1])).mean()
    log_det = np.abs(np.log(np.maximum(det, 1e-3))).mean()
    print(f"{name}: LNCC r {'/'.join(map(str, RADII))} {match}; volume kept {kept:.3f}, "
          f"mean |log det J| {log_det:.3f}")


def error_by_scale(error, soft, spacing):
    error = error * soft[..., None]
    parts = []
    for sigma in SMOOTHING_MM:
        weight = nd.gaussian_filter(soft.astype(float), sigma / spacing) + 1e-9
        smooth = np.stack([nd.gaussian_filter(error[..., c], sigma / spacing) / weight
                           for c in range(3)], -1)
        parts.append(f"{sigma} mm {np.linalg.norm(smooth, axis=-1)[soft].mean():.2f}")
    return ", ".join(parts)


def error_by_gap(length, soft, pair, spacing):
    labels = sitk.GetArrayFromImage(sitk.ReadImage(os.path.join(pair, "target_labels.nii.gz")))
    bones = [b["label"] for b in json.load(open(os.path.join(pair, "truth.json")))["bones"]]
    if len(bones) < 2:
        return "fewer than two bones"
    distances = np.sort(np.stack([nd.distance_transform_edt(labels != c, sampling=spacing)
                                  for c in bones]), axis=0)
    gap = distances[0] + distances[1]
    total = length[soft].sum()
    parts = []
    for lo, hi in ((0, 20), (20, 40), (40, np.inf)):
        m = soft & (gap >= lo) & (gap < hi)
        if m.any():
            parts.append(f"{lo}-{hi} mm: {length[m].mean():.2f} "
                         f"({length[m].sum() / total:.0%} of the summed error)")
    return ", ".join(parts)


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    pair, fields = sys.argv[1], sys.argv[2:]
    soft_image = sitk.ReadImage(os.path.join(pair, "mask_soft.nii.gz"))
    soft = sitk.GetArrayFromImage(soft_image) > 0
    spacing = np.array(soft_image.GetSpacing())[::-1]  # per numpy axis (z, y, x), mm
    scans = [sitk.ReadImage(os.path.join(pair, f"{name}.nii.gz"), sitk.sitkFloat64)
             for name in ("source", "target")]
    truth = read_field(os.path.join(pair, "truth_field.nii.gz"), soft_image)
    image_and_volume("truth", truth, scans, soft)
    truth_u = sitk.GetArrayFromImage(truth)
    for path in fields:
        field = read_field(path, soft_image)
        image_and_volume(path, field, scans, soft)
        error = sitk.GetArrayFromImage(field) - truth_u
        length = np.linalg.norm(error, axis=-1)
        print(f"  error {length[soft].mean():.2f} mm; its smooth part after "
              f"{error_by_scale(error, soft, spacing)}")
        print(f"  by d1 + d2 to the nearest two bones: {error_by_gap(length, soft, pair, spacing)}")


if __name__ == "__main__":
    main()
