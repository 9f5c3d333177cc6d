#!/usr/bin/env python3
"""Makes a two-pose test pair from one labelled knee scan, independently of posereg.

    scripts/make_pair.py --image IMG --labels LAB --degrees 45 --spacing 2.0 -o OUT [options]

Shares no code and no model with the registration: numpy and SimpleITK only, its own flexion
axis (a circle fitted to the posterior condyles, not posereg's axis finder), bone motions that
are not rotations about one axis (the tibia also turns internally and slides, the patella tilts,
the whole leg moves a little), and soft tissue moved by a polyrigid log-Euclidean flow from the
bent pose back to the straight one: each point moves with the weighted mean of the bones'
inverse twists, weights d⁻² exp(−d/15 mm) of its distance to each bone where that bone is at
that moment of the flow (posereg blends forward from the straight pose with dual quaternions
and d⁻⁵ weights, then inverts numerically), plus smooth bumps in soft tissue only. The flow does
not fold. Points inside a bent bone get that bone's motion exactly, so bones are exactly rigid.

Both scans are sampled from the same anti-aliased high-resolution scan onto grids of the asked
spacing, each with its own smooth multiplicative bias and Rician noise. The target's field of
view can be cut (--target-keep) so that a bone is only partly seen.

Writes into OUT: source.nii.gz, source_labels.nii.gz, target.nii.gz, target_labels.nii.gz
(1 body, 2-5 bones in the bent pose), mask_bone.nii.gz, mask_soft.nii.gz, truth_field.nii.gz
(ITK convention: on the target grid, LPS mm, target point -> source point), truth.json (bone
motions source -> target, RAS, posereg's transform format) and pair.json (the settings).
"""
import argparse
import json
import os

import numpy as np
import SimpleITK as sitk

BONES = {2: "femur", 3: "tibia", 4: "patella", 5: "fibula"}
FEMUR, TIBIA, PATELLA, FIBULA = 2, 3, 4, 5


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--image", required=True)
    p.add_argument("--labels", required=True)
    p.add_argument("--degrees", type=float, required=True, help="knee flexion of the target")
    p.add_argument("--spacing", type=float, default=1.0,
                   help="voxel size (mm) of both scans; no axis finer than the input's")
    p.add_argument("--target-keep", nargs=3, metavar=("AXIS", "FROM", "TO"), default=None,
                   help="keep only this fraction range of the target's voxel axis, e.g. 1 0 0.8")
    p.add_argument("--noise", type=float, default=0.02, help="Rician noise, share of the 99th percentile")
    p.add_argument("--bias", type=float, default=0.15, help="bias field amplitude (share)")
    p.add_argument("--bumps", type=float, default=1.5, help="soft-tissue bump amplitude (mm)")
    p.add_argument("--falloff", type=float, default=15.0,
                   help="soft tissue follows a bone d^-2 exp(-d/falloff) (mm) relative to the nearest")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("-o", "--out", required=True)
    return p.parse_args()


# ---- grids -------------------------------------------------------------------------------

def coarse_grid(image, spacing, keep=None):
    """An empty image covering `image`'s extent with voxels of at least `spacing` mm."""
    old_sp = np.array(image.GetSpacing())
    size = np.array(image.GetSize())
    new_sp = np.maximum(old_sp, spacing)
    new_size = np.floor(size * old_sp / new_sp).astype(int)
    first = np.zeros(3)
    if keep is not None:
        axis, lo, hi = int(keep[0]), float(keep[1]), float(keep[2])
        first[axis] = int(round(lo * new_size[axis]))
        new_size[axis] = int(round(hi * new_size[axis])) - int(first[axis])
    direction = np.array(image.GetDirection()).reshape(3, 3)
    corner = np.array(image.GetOrigin()) - direction @ (old_sp / 2)
    origin = corner + direction @ (new_sp * (first + 0.5))
    grid = sitk.Image([int(n) for n in new_size], sitk.sitkFloat32)
    grid.SetSpacing(new_sp.tolist())
    grid.SetOrigin(origin.tolist())
    grid.SetDirection(direction.ravel().tolist())
    return grid


def grid_points(grid):
    """World (LPS) coordinates of every voxel, shape (z, y, x, 3) as numpy orders them."""
    size = grid.GetSize()
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in size], indexing="ij"), -1).astype(float)
    direction = np.array(grid.GetDirection()).reshape(3, 3)
    world = (idx * np.array(grid.GetSpacing())) @ direction.T + np.array(grid.GetOrigin())
    return np.transpose(world, (2, 1, 0, 3))


def label_points(labels, code):
    arr = sitk.GetArrayFromImage(labels)
    zyx = np.argwhere(arr == code)
    direction = np.array(labels.GetDirection()).reshape(3, 3)
    xyz = zyx[:, ::-1].astype(float)
    return xyz, (xyz * np.array(labels.GetSpacing())) @ direction.T + np.array(labels.GetOrigin())


# ---- the joint: an axis fitted to the posterior condyles ----------------------------------

def condyle_axis(labels):
    """Flexion axis (point, unit direction, LPS): the sagittal-plane circle through the
    posterior condyles' surface, the axis along the voxel axis across the sagittal slices."""
    direction = np.array(labels.GetDirection()).reshape(3, 3)
    spacing = np.array(labels.GetSpacing())
    across = int(np.argmax(np.abs(direction[0])))  # the voxel axis nearest left-right
    inplane = [a for a in range(3) if a != across]
    xyz, world = label_points(labels, FEMUR)
    # The femur's long axis: which in-plane voxel axis its extent is largest along.
    extent = [np.ptp(xyz[:, a]) * spacing[a] for a in inplane]
    long_ax = inplane[int(np.argmax(extent))]
    ap_ax = inplane[1 - int(np.argmax(extent))]
    tibia_xyz, _ = label_points(labels, TIBIA)
    distal_sign = np.sign(tibia_xyz[:, long_ax].mean() - xyz[:, long_ax].mean())
    depth = distal_sign * xyz[:, long_ax] * spacing[long_ax]
    slab = depth > depth.max() - 30.0
    pts = xyz[slab]
    # Surface voxels of the slab facing away from the bone's middle, posterior-distal half:
    # the condyles' arc in the sagittal plane.
    a0 = pts[:, ap_ax] * spacing[ap_ax]
    a1 = pts[:, long_ax] * spacing[long_ax]
    arr = sitk.GetArrayFromImage(labels) == FEMUR
    shape = arr.shape[::-1]
    surface = np.zeros(len(pts), bool)
    for step in (-1, 1):
        for ax in inplane:
            n = pts.astype(int).copy()
            n[:, ax] += step
            inside = (n[:, ax] >= 0) & (n[:, ax] < shape[ax])
            nb = np.zeros(len(pts), bool)
            nb[inside] = arr[n[inside, 2], n[inside, 1], n[inside, 0]]
            surface |= ~nb
    # LPS: +y is posterior; the voxel axis `ap_ax` points posteriorly when its direction has +y.
    toward_back = np.sign(direction[1, ap_ax]) * (a0 - a0.mean()) > 0
    arc = surface & toward_back & (distal_sign * (a1 - a1.mean()) > -5.0)
    u, v = a0[arc], a1[arc]
    # Kasa circle fit: u² + v² = 2 c_u u + 2 c_v v + k.
    m = np.stack([2 * u, 2 * v, np.ones_like(u)], 1)
    c_u, c_v, _ = np.linalg.lstsq(m, u * u + v * v, rcond=None)[0]
    centre_idx = np.zeros(3)
    centre_idx[ap_ax] = c_u / spacing[ap_ax]
    centre_idx[long_ax] = c_v / spacing[long_ax]
    centre_idx[across] = pts[:, across].mean()
    point = (centre_idx * spacing) @ direction.T + np.array(labels.GetOrigin())
    axis = direction[:, across].copy()
    # Positive flexion swings the tibia posteriorly (LPS +y).
    _, tibia_world = label_points(labels, TIBIA)
    lever = tibia_world.mean(0) - point
    if np.cross(axis, lever)[1] < 0:
        axis = -axis
    superior = -distal_sign * direction[:, long_ax]
    return point, axis / np.linalg.norm(axis), superior, world


# ---- rigid motions: 4x4 matrices, their twists, and a vectorised exponential --------------

def rotation(axis, degrees, centre):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r = np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = centre - r @ centre
    return m


def translation(v):
    m = np.eye(4)
    m[:3, 3] = v
    return m


def twist(m):
    """log of a rigid motion: (omega, v) with exp(omega, v) = m."""
    r, t = m[:3, :3], m[:3, 3]
    theta = np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    if theta < 1e-12:
        return np.zeros(3), t.copy()
    w = theta / (2 * np.sin(theta)) * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    v_mat = np.eye(3) + (1 - np.cos(theta)) / theta**2 * k + (theta - np.sin(theta)) / theta**3 * k @ k
    return w, np.linalg.solve(v_mat, t)


def apply_twists(w, v, p):
    """exp(w, v) applied to points p, all arrays (..., 3)."""
    theta = np.linalg.norm(w, axis=-1, keepdims=True)
    safe = np.where(theta < 1e-9, 1.0, theta)
    a = np.where(theta < 1e-9, 1.0, np.sin(safe) / safe)
    b = np.where(theta < 1e-9, 0.5, (1 - np.cos(safe)) / safe**2)
    c = np.where(theta < 1e-9, 1 / 6, (safe - np.sin(safe)) / safe**3)
    cross = np.cross
    rp = p + a * cross(w, p) + b * cross(w, cross(w, p))
    tv = v + b * cross(w, v) + c * cross(w, cross(w, v))
    return rp + tv


def bone_motions(labels, degrees, rng):
    """Source -> target motions (LPS 4x4) of the bones present, and the axis used."""
    point, axis, superior, _ = condyle_axis(labels)
    arr = sitk.GetArrayFromImage(labels)
    centroid = {c: label_points(labels, c)[1].mean(0) for c in BONES if (arr == c).any()}
    # The whole leg moved a little between the scans.
    whole = translation(rng.uniform(-2, 2, 3)) @ rotation(rng.normal(size=3), rng.uniform(1, 3), point)
    tibia = (rotation(axis, degrees, point)
             @ rotation(superior, 0.10 * degrees, centroid.get(TIBIA, point))
             @ translation(0.015 * degrees * np.cross(axis, superior)))
    patella = (rotation(axis, 0.7 * degrees, point)
               @ rotation(superior, 0.05 * degrees, centroid.get(PATELLA, point)))
    local = {FEMUR: np.eye(4), TIBIA: tibia, FIBULA: tibia, PATELLA: patella}
    return {c: whole @ local[c] for c in centroid}, (point, axis)


# ---- the pull-back blend -----------------------------------------------------------------

def pulled(image, grid, transform, interpolator):
    return sitk.Resample(image, grid, transform, interpolator, 0.0, image.GetPixelID())


def affine_transform(m):
    t = sitk.AffineTransform(3)
    t.SetMatrix(m[:3, :3].ravel().tolist())
    t.SetTranslation(m[:3, 3].tolist())
    return t


def distance_to(mask):
    d = sitk.SignedMaurerDistanceMap(mask, insideIsPositive=False, squaredDistance=False,
                                     useImageSpacing=True)
    return np.maximum(sitk.GetArrayFromImage(d), 0.0)


def smooth_bumps(points, body, dmin, amplitude, rng, count=6, sigma=15.0, clear=8.0):
    """A smooth displacement (mm) in soft tissue: Gaussian bumps at random body points,
    faded to zero at the bones."""
    centres = points[body][rng.choice(int(body.sum()), count, replace=False)]
    out = np.zeros_like(points)
    for c in centres:
        g = np.exp(-np.sum((points - c) ** 2, -1) / (2 * sigma**2))
        out += amplitude * g[..., None] * rng.normal(size=3) / np.sqrt(3)
    fade = 1 - np.exp(-(dmin / clear) ** 2)
    return out * fade[..., None]


def world_to_index(grid):
    """The map world LPS (..., 3) -> continuous voxel index (x, y, z) of `grid`."""
    direction = np.array(grid.GetDirection()).reshape(3, 3)
    spacing, origin = np.array(grid.GetSpacing()), np.array(grid.GetOrigin())
    inverse = np.linalg.inv(direction) / spacing[:, None]
    return lambda w: (w - origin) @ inverse.T


def trilinear(volume, index):
    """volume (z, y, x) at continuous indices (..., 3 as x, y, z), clamped at the edges."""
    hi = np.array(volume.shape[::-1]) - 1
    i = np.clip(index, 0, hi)
    i0 = np.minimum(np.floor(i).astype(int), np.maximum(hi - 1, 0))
    t = i - i0
    out = 0.0
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = ((t[..., 0] if dx else 1 - t[..., 0]) * (t[..., 1] if dy else 1 - t[..., 1])
                     * (t[..., 2] if dz else 1 - t[..., 2]))
                out = out + w * volume[np.minimum(i0[..., 2] + dz, hi[2]),
                                       np.minimum(i0[..., 1] + dy, hi[1]),
                                       np.minimum(i0[..., 0] + dx, hi[0])]
    return out


def flow_weights(x, s, distance, twists, index_of, falloff):
    """Weights d⁻² exp(−d/falloff) of the bones at flow time s, normalised: bone j has then
    moved by exp(s·η_j), so x's distance to it is the bent bone's distance map at exp(−s·η_j) x.
    The exponential keeps a limb segment's tissue with its own bone away from the joint (with
    d⁻² alone a thigh muscle 30 mm from the femur and 90 mm from the tibia would turn with the
    tibia by a tenth of the flexion)."""
    d = np.stack([trilinear(dmap, index_of(apply_twists(-s * w, -s * v, x)))
                  for dmap, (w, v) in zip(distance, twists)], -1)
    inside = d <= 0
    near = d - d.min(-1, keepdims=True)  # the exponential relative to the nearest bone
    weights = np.where(inside.any(-1, keepdims=True), inside.astype(float),
                       np.exp(-near / falloff) / np.maximum(d, 1e-6) ** 2)
    return weights / weights.sum(-1, keepdims=True), d


def blended_step(x, weights, twists, h):
    omega = h * np.einsum("...j,jk->...k", weights, np.array([t[0] for t in twists]))
    vel = h * np.einsum("...j,jk->...k", weights, np.array([t[1] for t in twists]))
    return apply_twists(omega, vel, x)


def pull_back(labels_hi, grid, motions, rng, bump_mm, body_mask, steps, falloff):
    """Displacement (z,y,x,3 LPS) of every target voxel to its source point, and the target's
    bone labels on the grid. A polyrigid log-Euclidean flow from the bent pose to the straight
    one: each bone moves along its own one-parameter path exp(s·η_j), η_j = log M_j⁻¹, every
    other point with the weighted mean of the bones' twists, weights from the distances to the
    bones where they are at that time (flow_weights; midpoint rule, exact exponential per
    step). A bone's
    points keep weight 1 all the way, so bones are exactly rigid; the flow of a Lipschitz
    velocity does not fold."""
    p = grid_points(grid)
    distance, twists = [], []
    bone_labels = np.zeros(p.shape[:3], np.uint8)
    for code, m in motions.items():
        mask = sitk.Cast(labels_hi == code, sitk.sitkFloat32)
        bent = pulled(mask, grid, affine_transform(np.linalg.inv(m)), sitk.sitkLinear) >= 0.5
        bone_labels[sitk.GetArrayFromImage(bent) > 0] = code
        distance.append(distance_to(bent))
        twists.append(twist(np.linalg.inv(m)))
    index_of = world_to_index(grid)
    x, h = p.copy(), 1.0 / steps
    for k in range(steps):
        w, _ = flow_weights(x, k * h, distance, twists, index_of, falloff)
        middle = blended_step(x, w, twists, h / 2)
        w, _ = flow_weights(middle, (k + 0.5) * h, distance, twists, index_of, falloff)
        x = blended_step(x, w, twists, h)
    _, d0 = flow_weights(p, 0.0, distance, twists, index_of, falloff)
    body = body_mask & (bone_labels == 0)
    x += smooth_bumps(p, body, d0.min(-1), bump_mm, rng)
    return x - p, bone_labels


# ---- images --------------------------------------------------------------------------------

def antialiased(image, spacing):
    old = np.array(image.GetSpacing())
    sigma = 0.4 * np.sqrt(np.maximum(np.maximum(old, spacing) ** 2 - old**2, 0.0))
    f = sitk.Cast(image, sitk.sitkFloat32)
    for axis in np.flatnonzero(sigma > 0):
        f = sitk.RecursiveGaussian(f, float(sigma[axis]), direction=int(axis))
    return f


def shaded(array, grid, noise_sd, bias, rng):
    """array × a smooth random bias, with Rician noise."""
    p = grid_points(grid)
    centre, half = p.reshape(-1, 3).mean(0), np.ptp(p.reshape(-1, 3), 0) / 2
    x = (p - centre) / half
    terms = [x[..., 0], x[..., 1], x[..., 2], x[..., 0] * x[..., 1], x[..., 1] * x[..., 2],
             x[..., 0] ** 2 - 1 / 3, x[..., 2] ** 2 - 1 / 3]
    log_bias = sum(c * t for c, t in zip(rng.normal(size=len(terms)), terms))
    log_bias *= bias / max(np.abs(log_bias).max(), 1e-9)
    clean = array * np.exp(log_bias)
    n1, n2 = rng.normal(0, noise_sd, array.shape), rng.normal(0, noise_sd, array.shape)
    return np.sqrt((clean + n1) ** 2 + n2**2).astype(np.float32)


def image_like(array, grid, vector=False):
    out = sitk.GetImageFromArray(array, isVector=vector)
    out.SetOrigin(grid.GetOrigin())
    out.SetSpacing(grid.GetSpacing())
    out.SetDirection(grid.GetDirection())
    return out


def ras(m):
    f = np.diag([-1.0, -1.0, 1.0, 1.0])
    return f @ m @ f


def main():
    a = arguments()
    rng = np.random.default_rng(a.seed)
    image = sitk.ReadImage(a.image)
    labels = sitk.ReadImage(a.labels, sitk.sitkUInt8)
    motions, (point, axis) = bone_motions(labels, a.degrees, rng)
    smooth = antialiased(image, a.spacing)
    p99 = float(np.percentile(sitk.GetArrayViewFromImage(smooth), 99))
    body_hi = sitk.Cast(smooth > 0.08 * p99, sitk.sitkFloat32)
    source_grid = coarse_grid(image, a.spacing)
    target_grid = coarse_grid(image, a.spacing, a.target_keep)

    body_t = sitk.GetArrayFromImage(
        pulled(body_hi, target_grid, sitk.Transform(3, sitk.sitkIdentity), sitk.sitkLinear)) >= 0.5
    steps = max(16, int(np.ceil(abs(a.degrees) / 2)))
    disp, bent_labels = pull_back(labels, target_grid, motions, rng, a.bumps, body_t, steps,
                                  a.falloff)
    field = image_like(disp.astype(np.float64), target_grid, vector=True)
    to_source = sitk.DisplacementFieldTransform(sitk.Image(field))
    target_clean = sitk.GetArrayFromImage(pulled(smooth, target_grid, to_source, sitk.sitkLinear))
    body_bent = sitk.GetArrayFromImage(pulled(body_hi, target_grid, to_source, sitk.sitkLinear)) >= 0.5
    identity = sitk.Transform(3, sitk.sitkIdentity)
    source_clean = sitk.GetArrayFromImage(pulled(smooth, source_grid, identity, sitk.sitkLinear))
    source_labels = pulled(labels, source_grid, identity, sitk.sitkLabelGaussian)

    source = shaded(source_clean, source_grid, a.noise * p99, a.bias, rng)
    target = shaded(target_clean, target_grid, a.noise * p99, a.bias, rng)
    target_labels = np.where(bent_labels > 0, bent_labels, body_bent.astype(np.uint8))

    os.makedirs(a.out, exist_ok=True)
    write = lambda img, name: sitk.WriteImage(img, os.path.join(a.out, name), True)
    write(image_like(source, source_grid), "source.nii.gz")
    write(sitk.Cast(source_labels, sitk.sitkUInt8), "source_labels.nii.gz")
    write(image_like(target, target_grid), "target.nii.gz")
    write(image_like(target_labels.astype(np.uint8), target_grid), "target_labels.nii.gz")
    write(image_like((bent_labels > 0).astype(np.uint8), target_grid), "mask_bone.nii.gz")
    write(image_like(((target_labels == 1)).astype(np.uint8), target_grid), "mask_soft.nii.gz")
    write(image_like(disp.astype(np.float32), target_grid, vector=True), "truth_field.nii.gz")
    truth = {
        "space": "RAS",
        "bones": [{"label": c, "name": BONES[c], "matrix": ras(m).tolist()}
                  for c, m in sorted(motions.items())],
        "generator": "scripts/make_pair.py (independent of posereg)",
    }
    with open(os.path.join(a.out, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    settings = vars(a) | {"flexion_axis_lps": {"point": point.tolist(), "direction": axis.tolist()}}
    with open(os.path.join(a.out, "pair.json"), "w") as f:
        json.dump(settings, f, indent=1)


if __name__ == "__main__":
    main()
