//! CPU twin of shaders/nonrigid/rbf_nodes.wgsl, shared by the twins of rbf_lattice and
//! rbf_adjoint (which write its cube_of_distance out by lane).

/// World position (mm) of lattice node `a`, which sits on voxel a · step (per axis).
#[inline]
pub fn node_position(geometry: &[f64], a: [u32; 3], step: [u32; 4]) -> [f64; 3] {
    let v: [f64; 3] = std::array::from_fn(|r| (a[r] * step[r]) as f64);
    std::array::from_fn(|r| {
        let g = &geometry[4 * r..4 * r + 4];
        g[0] * v[0] + g[1] * v[1] + g[2] * v[2] + g[3]
    })
}
