// The broad phase of contacts between bodies, rebuilt from `state_in` before every force pass
// of a model of several bodies, as the core's contact module builds it: the active points
// sorted by a hash of their grid cell (cubes the size of the largest ball's diameter), in each
// bucket by index, so that every point meets its candidates in the same order on every run.
//
// `grid` holds, for B buckets (a power of two): counts [0, B), starts [B, 2B + 1) (bucket b's
// entries are [starts[b], starts[b + 1])), cursors [2B + 1, 3B + 1), then the sorted entries.
// The passes, in order: grid_count, grid_scan, grid_scatter, grid_sort.

fn grid_cell_of(p: vec3<f32>) -> vec3<i32> {
    return vec3<i32>(floor(p * P.grid_cell.y));
}

// The hash of a cell (the three large primes of Teschner et al. 2003).
fn grid_hash(c: vec3<i32>) -> u32 {
    let u = bitcast<vec3<u32>>(c);
    return (u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u);
}

fn grid_bucket(i: u32) -> u32 {
    return grid_hash(grid_cell_of(position(i))) & (P.counts.w - 1u);
}

// Counts the active points per bucket.
@compute @workgroup_size(64)
fn grid_count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x || (points[i].y & ACTIVE) == 0u) {
        return;
    }
    atomicAdd(&grid_rw[grid_bucket(i)], 1u);
}

var<workgroup> chunk_totals: array<u32, 256>;

// One workgroup: the counts become the starts (and the cursors) by an exclusive prefix sum,
// each thread over a run of buckets, and are zeroed for the next pass.
@compute @workgroup_size(256)
fn grid_scan(@builtin(local_invocation_index) t: u32) {
    let buckets = P.counts.w;
    let run = (buckets + 255u) / 256u;
    let lo = min(t * run, buckets);
    let hi = min(lo + run, buckets);
    var total = 0u;
    for (var b = lo; b < hi; b = b + 1u) {
        total = total + atomicLoad(&grid_rw[b]);
    }
    chunk_totals[t] = total;
    workgroupBarrier();
    var start = 0u;
    for (var u = 0u; u < t; u = u + 1u) {
        start = start + chunk_totals[u];
    }
    for (var b = lo; b < hi; b = b + 1u) {
        let count = atomicLoad(&grid_rw[b]);
        atomicStore(&grid_rw[buckets + b], start);
        atomicStore(&grid_rw[2u * buckets + 1u + b], start);
        atomicStore(&grid_rw[b], 0u);
        start = start + count;
    }
    if (t == 255u) {
        atomicStore(&grid_rw[2u * buckets], start);
    }
}

// Puts each active point into its bucket (in any order; grid_sort orders them).
@compute @workgroup_size(64)
fn grid_scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x || (points[i].y & ACTIVE) == 0u) {
        return;
    }
    let buckets = P.counts.w;
    let slot = atomicAdd(&grid_rw[2u * buckets + 1u + grid_bucket(i)], 1u);
    atomicStore(&grid_rw[3u * buckets + 1u + slot], i);
}

// Sorts each bucket's entries by point index (insertion sort: a bucket holds a few).
@compute @workgroup_size(64)
fn grid_sort(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let b = point_index(gid, groups);
    let buckets = P.counts.w;
    if (b >= buckets) {
        return;
    }
    let entries = 3u * buckets + 1u;
    let lo = atomicLoad(&grid_rw[buckets + b]);
    let hi = atomicLoad(&grid_rw[buckets + b + 1u]);
    for (var s = lo + 1u; s < hi; s = s + 1u) {
        let e = atomicLoad(&grid_rw[entries + s]);
        var t = s;
        while (t > lo && atomicLoad(&grid_rw[entries + t - 1u]) > e) {
            atomicStore(&grid_rw[entries + t], atomicLoad(&grid_rw[entries + t - 1u]));
            t = t - 1u;
        }
        atomicStore(&grid_rw[entries + t], e);
    }
}
