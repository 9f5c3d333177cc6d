// ssd_cells.wgsl: partial sums of c (a - b)^2 for the per-cell SSD, c = 1 where the first image
// holds data (is_covered), else 0: where the moving image has no data from the source scan its
// residual is not evidence of a poor fit.
//
// The volume is split into cells (cx, cy, cz): voxel i along an axis of n voxels belongs to
// cell floor(i * c / n). One invocation owns one (x, z) column and walks it along y, writing one
// partial sum per y-cell: partial[(z * nx + x) * cy + c]. Neighbouring invocations read
// neighbouring x, so loads coalesce. The host folds partials into cells in f64 in a fixed order
// (metric::fold_ssd_partials), so results are deterministic without atomics.
//
// Bindings (group 0):
//   0 uniform  SsdParams
//   1 storage  a: array<f32>        the first volume (e.g. warped source)
//   2 storage  b: array<f32>        the second volume (e.g. target)
//   3 storage  covered: array<f32>  the first volume's coverage
//   4 storage  partial: array<f32>  nz * nx * cy partial sums (read_write)
// Dispatch: workgroups (ceil(nx/64), nz, 1).

// Keep in sync with abi::SsdParams.
struct SsdParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
    cells: vec4<u32>,  // cx, cy, cz, unused
}

@group(0) @binding(0) var<uniform> params: SsdParams;
@group(0) @binding(1) var<storage, read> a: array<f32>;
@group(0) @binding(2) var<storage, read> b: array<f32>;
@group(0) @binding(3) var<storage, read> covered: array<f32>;
@group(0) @binding(4) var<storage, read_write> partial: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nx = params.dims.x;
    let ny = params.dims.y;
    let cy = params.cells.y;
    let x = gid.x;
    let z = gid.y;
    if (x >= nx || z >= params.dims.z) {
        return;
    }
    let dims = params.dims.xyz;
    for (var c = 0u; c < cy; c = c + 1u) {
        var sum = 0.0;
        for (var y = cell_start(c, ny, cy); y < cell_start(c + 1u, ny, cy); y = y + 1u) {
            let i = voxel_index(x, y, z, dims);
            let d = select(0.0, a[i] - b[i], is_covered(covered[i]));
            sum = sum + d * d;
        }
        partial[(z * nx + x) * cy + c] = sum;
    }
}
