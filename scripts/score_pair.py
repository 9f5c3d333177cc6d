#!/usr/bin/env python3
"""Scores a registration of a pair made by scripts/make_pair.py, independently of posereg.

    scripts/score_pair.py PAIR_DIR FIELD [--bones TRANSFORM_JSON] [--json | --row PAIR METHOD SECONDS]
    scripts/score_pair.py --header

FIELD is a displacement field in the ITK convention (posereg's field.nii.gz, elastix's
deformationField.nii, ANTs' warp, SimpleITK's): on the target grid, LPS mm, target point ->
source point. Prints the mean field error over the body, the bones and the soft tissue (the
pair's masks), and the folded share of the body (det J <= 0, central differences in world
space) with bone contacts apart: voxels whose difference stencil spans two bones of the
source labels (along one axis its two neighbours in two different bones, or all six neighbours
in bones, two different ones), where a field that keeps bones rigid jumps from one bone's
motion to the other's as they slide on each other (the pair's own true field has det J <= 0
at many of them too: the determinant measures the slide, not a fold); with --bones, each
bone's rotation error (degrees) and its translation error at the
bone's centroid (mm) against truth.json (RAS, source -> target, posereg's transform format).
The soft-tissue error is also split by how the pair's own truth changes the tissue's volume
(its det J): tissue kept within 0.8-1.25x its volume, and tissue squeezed or stretched beyond,
which real tissue, nearly incompressible, is not (the generator's polyrigid flow compresses
the tissue behind a deeply bent knee to a fraction of its volume).
Also the Pearson correlation of the source scan resampled through FIELD (SimpleITK, linear) with
the target scan over the target's body (target_labels > 0) where FIELD maps inside the source, so
that every tool's image match is measured the same way (key `correlation`; the share of the body
it covers, `correlation_share`).
--row prints one row of scripts/compare_elastix.sh's independent-pairs table instead (--header,
that table's header).
"""
import argparse
import json
import os
import sys

import numpy as np
import SimpleITK as sitk


def read_field(path, like):
    """The field at `path`, refused unless it lies on `like`'s grid: a field on a shifted or
    rescaled grid would be scored against the wrong voxels."""
    field = sitk.ReadImage(path, sitk.sitkVectorFloat64)
    if field.GetSize() != like.GetSize():
        raise SystemExit(f"{path}: grid {field.GetSize()} is not the pair's {like.GetSize()}")
    for what, tolerance in (("Origin", 1e-3), ("Spacing", 1e-5), ("Direction", 1e-5)):
        mine, theirs = (np.array(getattr(i, f"Get{what}")()) for i in (field, like))
        if np.abs(mine - theirs).max() > tolerance:
            text = lambda v: ", ".join(f"{x:.4f}" for x in v)  # noqa: E731
            raise SystemExit(f"{path}: {what.lower()} ({text(mine)}) is not the pair's "
                             f"({text(theirs)})")
    return field


def resampled(image, field, interpolator=sitk.sitkLinear):
    """`image` seen through `field` on the field's grid (0 where it maps outside), as an array."""
    transform = sitk.DisplacementFieldTransform(sitk.Image(field))
    return sitk.GetArrayFromImage(sitk.Resample(image, field, transform, interpolator, 0.0))


def jacobian_determinant(field):
    u = sitk.GetArrayFromImage(field)
    direction = np.array(field.GetDirection()).reshape(3, 3)
    spacing = np.array(field.GetSpacing())
    grads = np.stack([np.gradient(u, axis=2 - a) / spacing[a] for a in range(3)], -1)
    return np.linalg.det(np.einsum("...ij,jk->...ik", grads, direction.T) + np.eye(3))


def bone_contacts(field, pair):
    """True where the voxel's difference stencil (its six face neighbours, the voxel itself on a
    face) spans two bones of the pair's source labels (nearest voxel; the bones truth.json
    lists, not other codes such as a soft-tissue label) through `field`: along one axis its two
    neighbours in two different bones, or all six in bones, two different ones. A difference
    across the jump from one bone's motion to the other's measures their slide, not the field's
    derivative."""
    labels = sitk.ReadImage(os.path.join(pair, "source_labels.nii.gz"))
    mapped = resampled(labels, field, sitk.sitkNearestNeighbor)
    bones = [b["label"] for b in json.load(open(os.path.join(pair, "truth.json")))["bones"]]
    mapped = np.where(np.isin(mapped, bones), mapped, 0)
    padded = np.pad(mapped, 1, mode="edge")
    core = tuple(slice(1, -1) for _ in range(3))
    spans_along_an_axis = np.zeros(mapped.shape, bool)
    neighbours = []
    for axis in range(3):
        pair_of = []
        for step in (-1, 1):
            s = list(core)
            s[axis] = slice(1 + step, padded.shape[axis] - 1 + step)
            pair_of.append(padded[tuple(s)])
        lo, hi = pair_of
        spans_along_an_axis |= (lo > 0) & (hi > 0) & (lo != hi)
        neighbours += pair_of
    neighbours = np.stack(neighbours)
    all_in_bones = (neighbours > 0).all(0) & (neighbours != neighbours[0]).any(0)
    return spans_along_an_axis | all_in_bones


KEPT_VOLUME = (0.8, 1.25)


def by_truth_volume(error, soft, truth):
    """Soft-tissue error where the truth keeps the volume within KEPT_VOLUME and elsewhere."""
    det = jacobian_determinant(truth)
    kept = soft & (det >= KEPT_VOLUME[0]) & (det <= KEPT_VOLUME[1])
    strained = soft & ~kept
    mean = lambda m: float(error[m].mean()) if m.any() else float("nan")
    return {"soft_kept_mm": mean(kept), "soft_kept_share": float(kept.sum() / soft.sum()),
            "soft_strained_mm": mean(strained)}


def warped_correlation(pair, field, body):
    """Pearson correlation of the pair's source scan resampled through `field` (SimpleITK,
    linear) with its target scan, over the target's body where the field maps inside the
    source: the same image measure for every tool, whatever its own resampling."""
    source = sitk.ReadImage(os.path.join(pair, "source.nii.gz"), sitk.sitkFloat32)
    target = sitk.GetArrayFromImage(sitk.ReadImage(os.path.join(pair, "target.nii.gz"), sitk.sitkFloat32))
    warped = resampled(source, field)
    ones = sitk.Image(source.GetSize(), sitk.sitkUInt8) + 1
    ones.CopyInformation(source)
    inside = resampled(ones, field, sitk.sitkNearestNeighbor) > 0
    m = body & inside
    return float(np.corrcoef(warped[m], target[m])[0, 1]), float(m.sum() / body.sum())


def bone_errors(pair, transforms):
    truth = {b["label"]: np.array(b["matrix"]) for b in json.load(open(os.path.join(pair, "truth.json")))["bones"]}
    found = {b["label"]: (b["name"], np.array(b["matrix"])) for b in json.load(open(transforms))["bones"]}
    labels = sitk.ReadImage(os.path.join(pair, "source_labels.nii.gz"))
    arr = sitk.GetArrayFromImage(labels)
    direction = np.array(labels.GetDirection()).reshape(3, 3)
    out = {}
    for code, (name, m) in sorted(found.items()):
        if code not in truth or not (arr == code).any():
            continue
        idx = np.argwhere(arr == code)[:, ::-1].mean(0)
        lps = direction @ (idx * np.array(labels.GetSpacing())) + np.array(labels.GetOrigin())
        centroid = np.append(lps * [-1, -1, 1], 1.0)  # RAS
        diff = np.linalg.inv(truth[code]) @ m
        angle = np.degrees(np.arccos(np.clip((np.trace(diff[:3, :3]) - 1) / 2, -1, 1)))
        shift = np.linalg.norm((m @ centroid - truth[code] @ centroid)[:3])
        out[name] = {"degrees": float(angle), "mm": float(shift)}
    return out


def table_row(r, pair, method, seconds):
    bones = r.get("bones", {})
    worst = "—"
    if bones:
        name, e = max(bones.items(), key=lambda b: b[1]["degrees"])
        worst = f"{name} {e['degrees']:.2f}° / {max(b['mm'] for b in bones.values()):.2f} mm"
    return (f"| {pair} | {method} | {float(seconds):.1f} | {r['mean_mm']:.2f} | {r['bone_mm']:.2f} | "
            f"{r['soft_mm']:.2f} | {r['soft_kept_mm']:.2f} | {r['soft_strained_mm']:.2f} | "
            f"{r['correlation']:.3f} | {100 * r['folded_share']:.4f} | {worst} |")


TABLE_HEADER = ("| pair | method | wall s | body mm | bone mm | soft tissue mm | soft, volume kept mm | "
                "soft, volume strained mm | correlation | folded % | worst bone |\n"
                "|---|---|---|---|---|---|---|---|---|---|---|")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("pair")
    p.add_argument("field")
    p.add_argument("--bones")
    p.add_argument("--json", action="store_true")
    p.add_argument("--row", nargs=3, metavar=("PAIR", "METHOD", "SECONDS"))
    p.add_argument("--header", action="store_true", help="print the --row table's header and stop")
    if "--header" in sys.argv[1:]:
        print(TABLE_HEADER)
        return
    a = p.parse_args()
    mask = lambda name: sitk.GetArrayFromImage(sitk.ReadImage(os.path.join(a.pair, name))) > 0
    truth = sitk.ReadImage(os.path.join(a.pair, "truth_field.nii.gz"), sitk.sitkVectorFloat64)
    field = read_field(a.field, truth)
    error = np.linalg.norm(sitk.GetArrayFromImage(field) - sitk.GetArrayFromImage(truth), axis=-1)
    body, bone, soft = mask("target_labels.nii.gz"), mask("mask_bone.nii.gz"), mask("mask_soft.nii.gz")
    det = jacobian_determinant(field)
    contact = bone_contacts(field, a.pair)
    result = {
        "mean_mm": float(error[body].mean()),
        "bone_mm": float(error[bone].mean()),
        "soft_mm": float(error[soft].mean()),
        "folded_share": float((det[body & ~contact] <= 0).sum() / body.sum()),
        "min_jacobian": float(det[body & ~contact].min()),
        "bone_contact_share": float((det[body & contact] <= 0).sum() / body.sum()),
        **by_truth_volume(error, soft, truth),
    }
    result["correlation"], result["correlation_share"] = warped_correlation(a.pair, field, body)
    if a.bones:
        result["bones"] = bone_errors(a.pair, a.bones)
    if a.json:
        print(json.dumps(result))
        return
    if a.row:
        print(table_row(result, *a.row))
        return
    print(f"field error: body {result['mean_mm']:.2f} mm, bone {result['bone_mm']:.2f}, soft tissue "
          f"{result['soft_mm']:.2f}; folded {100 * result['folded_share']:.4f}% (min det J "
          f"{result['min_jacobian']:.3f}), {100 * result['bone_contact_share']:.4f}% more at bone contacts")
    print(f"  soft tissue whose volume the truth keeps within {KEPT_VOLUME[0]}-{KEPT_VOLUME[1]}x "
          f"({100 * result['soft_kept_share']:.0f}%): {result['soft_kept_mm']:.2f} mm; squeezed or "
          f"stretched beyond: {result['soft_strained_mm']:.2f} mm")
    print(f"  warped source's correlation with the target over the body: {result['correlation']:.4f} "
          f"({100 * result['correlation_share']:.1f}% of the body mapped inside the source)")
    for name, e in result.get("bones", {}).items():
        print(f"  {name:<8} {e['degrees']:.2f}° {e['mm']:.2f} mm")


if __name__ == "__main__":
    main()
