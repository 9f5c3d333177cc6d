#!/usr/bin/env python3
"""PICSL greedy as a peer for scripts/compare_elastix.sh.

    scripts/greedy.py FIXED MOVING OUT_DIR        (pip install picsl-greedy)

Greedy's own recipe through its Python API (picsl_greedy.Greedy3D, the `greedy` command's
arguments): an affine stage (12 dof, NCC over a 2x2x2 patch, image centres matched first,
100x50x10 iterations over three resolutions), then a deformable stage from it (NCC 2x2x2,
100x50x10, greedy's default smoothing), then greedy's reslicing (-rc) composing the warp and the
affine into one displacement field on the fixed grid. Writes OUT_DIR/field.nii.gz (ITK
convention: on the fixed grid, LPS mm, fixed point -> moving point, affine included; checked
here: the moving scan resampled through it by SimpleITK must match greedy's own reslice,
OUT_DIR/greedy_resliced.nii.gz), OUT_DIR/warped.nii.gz (that resample), affine.mat and
warp.nii.gz (greedy's own outputs). THREADS (default 2) sets greedy's threads.
"""
import io
import os
import sys

import numpy as np
import SimpleITK as sitk
from picsl_greedy import Greedy3D


def run(greedy, command):
    log = io.StringIO()
    try:
        greedy.execute(command, out=log, err=log)
    except Exception:
        sys.stderr.write(log.getvalue())
        raise


def main():
    fixed, moving, out = sys.argv[1:4]
    os.makedirs(out, exist_ok=True)
    path = lambda name: os.path.join(out, name)
    threads = int(os.environ.get("THREADS", 2))
    g = Greedy3D()
    run(g, f"-d 3 -threads {threads} -a -dof 12 -m NCC 2x2x2 -i {fixed} {moving} "
           f"-ia-image-centers -n 100x50x10 -o {path('affine.mat')}")
    run(g, f"-d 3 -threads {threads} -m NCC 2x2x2 -i {fixed} {moving} -it {path('affine.mat')} "
           f"-n 100x50x10 -o {path('warp.nii.gz')}")
    run(g, f"-d 3 -threads {threads} -rf {fixed} -rc {path('field.nii.gz')} "
           f"-r {path('warp.nii.gz')} {path('affine.mat')}")
    run(g, f"-d 3 -threads {threads} -rf {fixed} -rm {moving} {path('greedy_resliced.nii.gz')} "
           f"-r {path('warp.nii.gz')} {path('affine.mat')}")

    # One ITK displacement field on the fixed grid, checked against greedy's own reslice.
    target = sitk.ReadImage(fixed, sitk.sitkFloat32)
    field = sitk.ReadImage(path("field.nii.gz"), sitk.sitkVectorFloat64)
    field.CopyInformation(target)  # greedy writes the fixed grid; drop header rounding
    source = sitk.ReadImage(moving, sitk.sitkFloat32)
    warped = sitk.Resample(source, target, sitk.DisplacementFieldTransform(sitk.Image(field)),
                           sitk.sitkLinear, 0.0)
    theirs = sitk.GetArrayFromImage(sitk.ReadImage(path("greedy_resliced.nii.gz"), sitk.sitkFloat32))
    ours = sitk.GetArrayFromImage(warped)
    both = (ours != 0) & (theirs != 0)
    r = np.corrcoef(ours[both], theirs[both])[0, 1]
    gap = np.abs(ours[both] - theirs[both]).mean() / max(np.abs(theirs[both]).mean(), 1e-12)
    print(f"greedy.py: field vs greedy's reslice: correlation {r:.5f}, mean |difference| "
          f"{100 * gap:.2f}% of the mean intensity")
    if r < 0.99:
        raise SystemExit("greedy.py: the composed field does not reproduce greedy's reslice")
    sitk.WriteImage(sitk.Cast(field, sitk.sitkVectorFloat32), path("field.nii.gz"))
    sitk.WriteImage(warped, path("warped.nii.gz"))


if __name__ == "__main__":
    main()
