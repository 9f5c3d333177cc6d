// rbf_nodes.wgsl: helpers of the f64 kernels over lattice nodes (rbf_lattice, rbf_adjoint),
// which declare `params: RbfLatticeParams` and `geometry` (the target grid's voxel → world rows, 3 × 4 f64). Mirrored in
// src/cpu/nonrigid/rbf_nodes.rs.

// Keep in sync with abi::RbfLatticeParams.
struct RbfLatticeParams {
    lattice: vec4<u32>,  // lx, ly, lz, unused
    step: vec4<u32>,     // lattice step along x, y, z (voxels), unused
    chunks: vec4<u32>,   // nodes, nodes per chunk, chunks (rbf_adjoint), unused
    points: u32,         // the spline's control points
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// World position (mm) of lattice node `a`, which sits on voxel a · step (per axis).
fn node_position(a: vec3<u32>, step: vec3<u32>) -> vec3<f64> {
    let v = vec3<f64>(f64(a.x * step.x), f64(a.y * step.y), f64(a.z * step.z));
    return vec3<f64>(
        geometry[0] * v.x + geometry[1] * v.y + geometry[2] * v.z + geometry[3],
        geometry[4] * v.x + geometry[5] * v.y + geometry[6] * v.z + geometry[7],
        geometry[8] * v.x + geometry[9] * v.y + geometry[10] * v.z + geometry[11],
    );
}

// φ(|x − c|) = |x − c|³, the cubic radial basis.
fn cube_of_distance(x: vec3<f64>, c: vec3<f64>) -> f64 {
    let dx = x.x - c.x;
    let dy = x.y - c.y;
    let dz = x.z - c.z;
    let d = sqrt(dx * dx + dy * dy + dz * dz);
    return d * d * d;
}
