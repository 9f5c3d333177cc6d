"""Writes oblique_nibabel.nii.gz and its expected values with nibabel (run once; outputs are
committed so the Rust tests read a file made by another tool without needing Python).

    python3 tests/data/make_oblique.py
"""
import json
import os

import nibabel as nib
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
rng = np.random.default_rng(7)
# int16 storage with a non-trivial slope/intercept, so the reader must apply scl_slope/scl_inter.
raw = rng.integers(-300, 300, size=(5, 6, 7)).astype(np.int16)
angle = np.deg2rad(20.0)
rot = np.array([
    [np.cos(angle), -np.sin(angle), 0.0],
    [np.sin(angle) * np.cos(0.3), np.cos(angle) * np.cos(0.3), -np.sin(0.3)],
    [np.sin(angle) * np.sin(0.3), np.cos(angle) * np.sin(0.3), np.cos(0.3)],
])
zooms = np.diag([0.9, 1.1, 2.0])
affine = np.eye(4)
affine[:3, :3] = rot @ zooms
affine[:3, 3] = [-12.5, 30.25, 7.0]
def write(name, sform_code, qform_code, kind=nib.Nifti1Image, header=None):
    img = kind(raw, affine, header=header)
    img.header.set_data_dtype(np.int16)
    img.header.set_slope_inter(0.5, 10.0)
    img.header.set_xyzt_units("mm")
    img.set_sform(affine if sform_code else None, code=sform_code)
    img.set_qform(affine, code=qform_code)
    path = os.path.join(here, name)
    nib.save(img, path)
    return path


# Both forms set (the usual case) and a qform-only file (exercises the quaternion decoding).
path = write("oblique_nibabel.nii.gz", sform_code=2, qform_code=1)
qpath = write("oblique_qform_only.nii.gz", sform_code=0, qform_code=1)
# The same image as NIfTI-2, as a big-endian .hdr/.img pair, and with a header extension that
# moves vox_offset past 352: what the reader must place exactly like the plain file.
write("oblique_nifti2.nii.gz", sform_code=2, qform_code=1, kind=nib.Nifti2Image)
write("oblique_pair_be.hdr", sform_code=2, qform_code=1, kind=nib.Nifti1Pair,
      header=nib.nifti1.Nifti1PairHeader(endianness=">"))
ext = nib.Nifti1Image(raw, affine)
ext.header.set_data_dtype(np.int16)
ext.header.set_slope_inter(0.5, 10.0)
ext.set_sform(affine, code=2)
ext.set_qform(affine, code=1)
ext.header.extensions.append(nib.nifti1.Nifti1Extension("comment", b"posereg reader test " * 6))
nib.save(ext, os.path.join(here, "oblique_extension.nii"))
back = nib.load(path)
qback = nib.load(qpath)
values = np.asarray(back.get_fdata(dtype=np.float64))
expected = {
    "note": "written by make_oblique.py with nibabel " + nib.__version__,
    "shape": list(back.shape),
    "affine": back.affine.tolist(),
    "qform_only_affine": qback.affine.tolist(),
    "sform_code": int(back.header["sform_code"]),
    "qform_code": int(back.header["qform_code"]),
    "orientation": "".join(nib.aff2axcodes(back.affine)),
    # read from the bytes: nibabel's loaded header reports vox_offset 0 for single files
    "extension_vox_offset": int(np.frombuffer(
        open(os.path.join(here, "oblique_extension.nii"), "rb").read()[108:112], "<f4")[0]),
    # values in x-fastest (NIfTI file) order, after scaling
    "values": values.ravel(order="F").tolist(),
}
with open(os.path.join(here, "oblique_nibabel.json"), "w") as f:
    json.dump(expected, f, indent=1)
print(back.affine)
print(qback.affine)
