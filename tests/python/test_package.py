"""The Python package (`pip install .`): a small phantom pair registered through it gives the
same field bytes and the same report.json (timings and the inputs' names apart) as the command
line, SimpleITK images go in and come back on their grids, and
bad input raises ValueError naming it. Run by scripts/test after the package is installed.

POSEREG names the command-line binary (default target/release/posereg).
"""

import json
import os
import subprocess

import nibabel as nib
import numpy as np
import pytest
import SimpleITK as sitk

import posereg

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BINARY = os.environ.get("POSEREG", os.path.join(ROOT, "target", "release", "posereg"))
FAST = {"adaptive": {"iterations": "3x3x3"}}


def cli(*args):
    done = subprocess.run([BINARY, *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A quarter phantom straight and bent 30°, and the command line's registration of it."""
    d = tmp_path_factory.mktemp("pair")
    cli("phantom", "--size", "quarter", "--flexion", 0, "--seed", 1, "-q", "-o", d / "s")
    cli("phantom", "--size", "quarter", "--flexion", 30, "--seed", 2, "-q", "-o", d / "t")
    (d / "fast.json").write_text('{"adaptive": {"iterations": "3x3x3"}}')
    paths = {"source": d / "s" / "image.nii.gz", "labels": d / "s" / "labels.nii.gz",
             "target": d / "t" / "image.nii.gz"}
    cli("register", "--source", paths["source"], "--source-labels", paths["labels"],
        "--target", paths["target"], "--config", d / "fast.json", "--device", "cpu",
        "--threads", 2, "-q", "-o", d / "cli")
    field = np.asarray(nib.load(d / "cli" / "field.nii.gz").dataobj)[:, :, :, 0, :]
    return paths, field, json.loads((d / "cli" / "report.json").read_text())


@pytest.fixture(scope="module")
def from_arrays(pair):
    """The pair registered from nibabel arrays with their affines, as the CLI registered it."""
    paths, _, _ = pair
    src, lab, tgt = (nib.load(paths[k]) for k in ("source", "labels", "target"))
    return posereg.register(src.get_fdata(dtype=np.float32), np.asarray(lab.dataobj),
                            tgt.get_fdata(dtype=np.float32), source_affine=src.affine,
                            target_affine=tgt.affine, threads=2, **FAST)


def test_arrays_with_affines_give_the_command_lines_field(pair, from_arrays):
    paths, cli_field, _ = pair
    src, tgt, r = nib.load(paths["source"]), nib.load(paths["target"]), from_arrays
    assert r.field.shape == cli_field.shape and r.field.dtype == np.float32
    assert r.field.tobytes() == np.ascontiguousarray(cli_field).tobytes()
    assert r.warped.shape == tgt.shape and np.allclose(r.target_affine, tgt.affine)
    assert r.inverse_field.shape == src.shape + (3,)
    assert r.report["correlation"]["after"] > r.report["correlation"]["before"]
    assert {b["name"] for b in r.transforms["bones"]} >= {"femur", "tibia", "patella"}
    flexion = r.kinematics["joints"][0]["quantities"][0]
    assert flexion["name"] == "flexion" and abs(flexion["change"] - 30) < 3


def test_simpleitk_images_keep_their_grids(pair):
    paths, cli_field, _ = pair
    src, lab, tgt = (sitk.ReadImage(str(paths[k])) for k in ("source", "labels", "target"))
    r = posereg.register(src, lab, tgt, threads=2, **FAST)
    for image, like in ((r.warped, tgt), (r.field, tgt), (r.jacobian, tgt),
                        (r.inverse_field, src)):
        assert image.GetSize() == like.GetSize()
        assert np.allclose(image.GetOrigin(), like.GetOrigin(), atol=1e-5)
        assert np.allclose(image.GetSpacing(), like.GetSpacing(), atol=1e-6)
        assert np.allclose(image.GetDirection(), like.GetDirection(), atol=1e-6)
    field = sitk.GetArrayFromImage(r.field).transpose(2, 1, 0, 3)
    assert np.array_equal(field, cli_field)
    # The field is ITK's: SimpleITK resampling the source through it gives the warped source.
    transform = sitk.DisplacementFieldTransform(sitk.Cast(r.field, sitk.sitkVectorFloat64))
    moved = sitk.Resample(src, tgt, transform, sitk.sitkLinear, 0.0)
    inside = sitk.GetArrayFromImage(tgt) > 0
    a, b = sitk.GetArrayFromImage(moved)[inside], sitk.GetArrayFromImage(r.warped)[inside]
    assert np.corrcoef(a, b)[0, 1] > 0.999


def test_bad_input_raises_naming_it(pair):
    paths, _, _ = pair
    src, tgt = nib.load(paths["source"]), nib.load(paths["target"])
    no_bones = np.zeros(src.shape, np.uint16)
    with pytest.raises(ValueError, match="source_labels"):
        posereg.register(src.get_fdata(), no_bones, tgt.get_fdata(), source_affine=src.affine,
                         target_affine=tgt.affine)
    with pytest.raises(ValueError, match="affine"):
        posereg.register(src.get_fdata(), no_bones, tgt.get_fdata())
    with pytest.raises(ValueError, match="nonsense"):
        posereg.register(src.get_fdata(), np.asarray(nib.load(paths["labels"]).dataobj),
                         tgt.get_fdata(), source_affine=src.affine, target_affine=tgt.affine,
                         adaptive={"nonsense": 1})


def without_timings(report, at=""):
    """report.json without what differs between two identical runs or names the inputs: wall
    times, the finishing time, the command line, where the inputs came from. Returns the rest
    and the keys left out (their paths)."""
    if not isinstance(report, dict):
        return report, []
    kept, dropped = {}, []
    for key, value in report.items():
        path = f"{at}.{key}"
        if key in ("command_line", "inputs", "finished_unix_seconds") or key.endswith("seconds"):
            dropped.append(path)
        else:
            kept[key], more = without_timings(value, path)
            dropped += more
    return kept, dropped


def test_python_writes_the_command_lines_report(pair, from_arrays):
    _, _, cli_report = pair
    ours, dropped = without_timings(from_arrays.report)
    theirs, _ = without_timings(cli_report)
    assert ".seconds" in dropped and ".inputs" in dropped
    assert len(ours) >= 12
    assert ours == theirs


def test_nan_voxels_are_refused_as_the_command_line_refuses_them(pair):
    paths, _, _ = pair
    src, lab, tgt = (nib.load(paths[k]) for k in ("source", "labels", "target"))
    source = src.get_fdata(dtype=np.float32)
    source[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match="source.*non-finite"):
        posereg.register(source, np.asarray(lab.dataobj), tgt.get_fdata(dtype=np.float32),
                         source_affine=src.affine, target_affine=tgt.affine)


def test_paths_are_read_as_the_command_line_reads_them(pair):
    paths, cli_field, cli_report = pair
    r = posereg.register(paths["source"], paths["labels"], str(paths["target"]), threads=2, **FAST)
    assert r.field.dtype == np.float32 and r.field.shape == cli_field.shape
    assert r.field.tobytes() == np.ascontiguousarray(cli_field).tobytes()
    assert np.allclose(r.target_affine, nib.load(paths["target"]).affine, atol=1e-5)
    ours, dropped = without_timings({**r.report, "inputs": None})
    theirs, _ = without_timings({**cli_report, "inputs": None})
    assert ours == theirs
    assert r.report["inputs"] == {**cli_report["inputs"]}


def bad_input_cases(paths, tmp):
    """(name, arguments, exception, words the message holds) for posereg.register."""
    src, lab, tgt = (nib.load(paths[k]) for k in ("source", "labels", "target"))
    s, l, t = src.get_fdata(dtype=np.float32), np.asarray(lab.dataobj), tgt.get_fdata(dtype=np.float32)
    A, B = src.affine, tgt.affine

    def arrays(source=s, labels=l, target=t, source_affine=A, target_affine=B, **kw):
        return dict(source=source, source_labels=labels, target=target,
                    source_affine=source_affine, target_affine=target_affine, **kw)

    def with_value(array, index, value):
        array = array.copy()
        array[index] = value
        return array

    singular = A.copy()
    singular[:3, 0] = 0
    corrupt = tmp / "corrupt.nii.gz"
    corrupt.write_bytes(b"not a nifti file at all")
    truncated = tmp / "truncated.nii.gz"
    truncated.write_bytes(paths["source"].read_bytes()[:300])
    return [
        ("source 2-D", arrays(source=s[:, :, 0]), ValueError, ["source", "3-D"]),
        ("target 4-D", arrays(target=t[..., None]), ValueError, ["target", "3-D"]),
        ("labels 2-D", arrays(labels=l[:, :, 0]), ValueError, ["source_labels", "3-D"]),
        ("source NaN", arrays(source=with_value(s, (3, 4, 5), np.nan)), ValueError, ["source", "non-finite"]),
        ("source +Inf", arrays(source=with_value(s, (0, 0, 0), np.inf)), ValueError, ["source", "non-finite"]),
        ("target -Inf", arrays(target=with_value(t, (1, 2, 3), -np.inf)), ValueError, ["target", "non-finite"]),
        ("target NaN everywhere", arrays(target=np.full_like(t, np.nan)), ValueError, ["target", "non-finite"]),
        ("labels fractional", arrays(labels=l + 0.5), ValueError, ["source_labels", "whole"]),
        ("labels negative", arrays(labels=with_value(l.astype(np.int32), (0, 0, 0), -1)), ValueError, ["source_labels"]),
        ("labels above 65535", arrays(labels=with_value(l.astype(np.int64), (0, 0, 0), 70000)), ValueError, ["source_labels"]),
        ("labels without bones", arrays(labels=np.zeros_like(l)), ValueError, ["source_labels"]),
        ("labels on another grid", arrays(labels=l[:-1]), ValueError, ["source_labels", "grid"]),
        ("source constant", arrays(source=np.zeros_like(s)), ValueError, ["source"]),
        ("target constant", arrays(target=np.ones_like(t)), ValueError, ["target"]),
        ("source affine missing", arrays(source_affine=None), ValueError, ["source", "affine"]),
        ("target affine missing", arrays(target_affine=None), ValueError, ["target", "affine"]),
        ("source affine 3x3", arrays(source_affine=A[:3, :3]), ValueError, ["source", "affine"]),
        ("source affine singular", arrays(source_affine=singular), ValueError, ["source", "zero axis"]),
        ("target affine NaN", arrays(target_affine=with_value(B, (0, 3), np.nan)), ValueError, ["finite"]),
        ("scans apart", arrays(target_affine=with_value(B, (0, 3), 1e6)), ValueError, ["target", "overlap"]),
        ("unknown section", arrays(nonsense={"a": 1}), ValueError, ["settings keyword arguments", "nonsense"]),
        ("unknown key", arrays(adaptive={"nonsense": 1}), ValueError, ["settings keyword arguments", "nonsense"]),
        ("threshold below 1", arrays(adaptive={"threshold": "0.5"}), ValueError, ["adaptive.threshold"]),
        ("iterations text", arrays(adaptive={"iterations": "many"}), ValueError, ["iterations"]),
        ("dense step 0", arrays(dense={"step_mm": 0.0}), ValueError, ["dense.step_mm"]),
        ("levels 9", arrays(adaptive={"levels": 9}), ValueError, ["adaptive.levels"]),
        ("bones naming soft tissue", arrays(init={"bones": [1]}), ValueError, ["init.bones"]),
        ("bone absent", arrays(init={"bones": [77]}), ValueError, ["source_labels", "77"]),
        ("threads -1", arrays(threads=-1), ValueError, ["threads"]),
        ("threads text", arrays(threads="2"), TypeError, ["threads"]),
        ("threads 1.5", arrays(threads=1.5), TypeError, ["threads"]),
        ("threads True", arrays(threads=True), TypeError, ["threads"]),
        ("device tpu", arrays(device="tpu"), ValueError, ["device"]),
        ("device 3", arrays(device=3), TypeError, ["device"]),
        ("progress text", arrays(progress="yes"), TypeError, ["progress"]),
        ("paths mixed with arrays", dict(source=paths["source"], source_labels=l, target=t,
                                         target_affine=B), TypeError, ["paths"]),
        ("path missing", dict(source=tmp / "absent.nii.gz", source_labels=paths["labels"],
                              target=paths["target"]), ValueError, ["absent.nii.gz"]),
        ("path corrupt", dict(source=corrupt, source_labels=paths["labels"],
                              target=paths["target"]), ValueError, ["corrupt.nii.gz"]),
        ("path truncated", dict(source=truncated, source_labels=paths["labels"],
                                target=paths["target"]), ValueError, ["truncated.nii.gz"]),
        ("labels path is the target", dict(source=paths["source"], source_labels=paths["target"],
                                          target=paths["target"]), ValueError, ["image.nii.gz"]),
    ]


def test_bad_input_table(pair, tmp_path):
    paths, _, _ = pair
    cases = bad_input_cases(paths, tmp_path)
    assert len(cases) >= 30
    failures = []
    for name, arguments, exception, words in cases:
        try:
            posereg.register(**arguments)
            failures.append(f"{name}: no error")
        except exception as e:
            missing = [w for w in words if w not in str(e)]
            if missing:
                failures.append(f"{name}: {e!r} does not name {missing}")
        except Exception as e:  # noqa: BLE001 - any other kind is a failure of the table
            failures.append(f"{name}: {type(e).__name__} {e}")
    assert not failures, "\n".join(failures)
