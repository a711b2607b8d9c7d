// The passes that find the touches between bodies in the stage in `state_in`, before every force
// pass of a model with contacts between bodies (CONTACTS), as the core's contact::bodies and
// broad_phase find them (see contact.wgsl for the surfaces and the records):
//
// 1. the cell grid: every kept cell of every body into a hashed uniform grid (cubes of the
//    largest lattice spacing) by the grid cells its box (as deformed now) overlaps, by a counting
//    sort (cells_count, cells_scan, cells_scatter), each bucket then sorted by cell (cells_sort),
//    so that every sample meets its candidates in the cells' order, as on the core;
// 2. the touches (touch): each sample, at its cell's corners' trilinear interpolation, looks
//    among the cells in its grid cell for the first of another body that holds it (Newton's
//    method on the cell's trilinear map); where that body's interpolated signed distance is
//    negative there, the sample is −φ/|∇φ| deep along n = ∇φ/|∇φ| and feels the penalty, damping
//    and friction of the core's touch_force; its record says so;
// 3. the touches listed per cell of the other body, in the samples' order (touches_scan,
//    touches_scatter, touches_sort), for the force pass's gather (`contacts_on`).
//
// The contact buffer (`grid_rw` here), in words, for B buckets (a power of two), C cells and S
// samples (see `Params`): the buckets' counts [0, B), starts [B, 2B + 1) (bucket b's entries
// are [starts[b], starts[b + 1]), cut at the room for entries) and cursors [2B + 1, 3B + 1);
// the entries (cell indices); per cell its box (lo, hi: six f32), then the touches' counts,
// starts (C + 1) and cursors per cell; the touches (sample indices) by cell; per sample its
// record (eight words). Every count is zero between passes (the scans leave them so).

// The grid cell of a point.
fn grid_cell_of(p: vec3<f32>) -> vec3<f32> {
    return floor(p * P.grid_cell.y);
}

// The hash of a grid cell (the three large primes of Teschner et al. 2003).
fn grid_hash(c: vec3<i32>) -> u32 {
    let u = bitcast<vec3<u32>>(c);
    return (u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u);
}

fn bucket_of(c: vec3<i32>) -> u32 {
    return grid_hash(c) & (P.counts.w - 1u);
}

// Grid cells one cell's box may overlap along an axis, less one, at most (the core's MAX_SPAN):
// a cell stretched further is torn, and left out.
const MAX_SPAN: f32 = 16.0;

fn word_f(w: u32) -> f32 {
    return bitcast<f32>(atomicLoad(&grid_rw[w]));
}

fn store_f(w: u32, x: f32) {
    atomicStore(&grid_rw[w], bitcast<u32>(x));
}

fn finite3(p: vec3<f32>) -> bool {
    return !(not_finite(p.x) || not_finite(p.y) || not_finite(p.z));
}

// The box of cell g at the last cells_count: lo, hi (hi.x < lo.x: torn, in no grid cell).
struct Box {
    lo: vec3<f32>,
    hi: vec3<f32>,
}

fn cell_box(g: u32) -> Box {
    let at = P.grid_at.y + 6u * g;
    return Box(
        vec3<f32>(word_f(at), word_f(at + 1u), word_f(at + 2u)),
        vec3<f32>(word_f(at + 3u), word_f(at + 4u), word_f(at + 5u)),
    );
}

// The cell's lower corner (model index).
fn cell_corner(g: u32) -> u32 {
    return scene[P.contact_at.y + g].x;
}

// Cell g's box as deformed now, and how many entries each bucket gets.
@compute @workgroup_size(64)
fn cells_count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let g = point_index(gid, groups);
    if (g >= P.contact.y) {
        return;
    }
    let c = cell_corner(g);
    let b = points[c].y & BODY_BITS;
    var lo = position(c);
    var hi = lo;
    var finite = finite3(lo);
    for (var k = 1u; k < 8u; k = k + 1u) {
        let q = position(c + corner_offset(b, k));
        finite = finite && finite3(q);
        lo = min(lo, q);
        hi = max(hi, q);
    }
    let first = grid_cell_of(lo);
    let last = grid_cell_of(hi);
    let at = P.grid_at.y + 6u * g;
    // A cell torn across the box (a step blowing up, which the step then rejects) is left out
    // rather than entered in thousands of buckets.
    let torn = !(finite3(first) && finite3(last)) || any(last - first > vec3<f32>(MAX_SPAN));
    if (!finite || torn) {
        store_f(at, 0.0);
        store_f(at + 1u, 0.0);
        store_f(at + 2u, 0.0);
        store_f(at + 3u, -1.0);
        store_f(at + 4u, -1.0);
        store_f(at + 5u, -1.0);
        return;
    }
    store_f(at, lo.x);
    store_f(at + 1u, lo.y);
    store_f(at + 2u, lo.z);
    store_f(at + 3u, hi.x);
    store_f(at + 4u, hi.y);
    store_f(at + 5u, hi.z);
    let i0 = vec3<i32>(first);
    let span = vec3<u32>(vec3<i32>(last) - i0);
    for (var x = 0u; x <= span.x; x = x + 1u) {
        for (var y = 0u; y <= span.y; y = y + 1u) {
            for (var z = 0u; z <= span.z; z = z + 1u) {
                atomicAdd(&grid_rw[bucket_of(i0 + vec3<i32>(vec3<u32>(x, y, z)))], 1u);
            }
        }
    }
}

var<workgroup> chunk_totals: array<u32, 256>;

// One workgroup: n counts at `counts` become starts at `starts` (n + 1 of them) and cursors at
// `cursors` by an exclusive prefix sum, each thread over a run of them, and are zeroed for the
// next pass.
fn scan(t: u32, n: u32, counts: u32, starts: u32, cursors: u32) {
    let run = (n + 255u) / 256u;
    let lo = min(t * run, n);
    let hi = min(lo + run, n);
    var total = 0u;
    for (var b = lo; b < hi; b = b + 1u) {
        total = total + atomicLoad(&grid_rw[counts + b]);
    }
    chunk_totals[t] = total;
    workgroupBarrier();
    var start = 0u;
    for (var u = 0u; u < t; u = u + 1u) {
        start = start + chunk_totals[u];
    }
    for (var b = lo; b < hi; b = b + 1u) {
        let count = atomicLoad(&grid_rw[counts + b]);
        atomicStore(&grid_rw[starts + b], start);
        atomicStore(&grid_rw[cursors + b], start);
        atomicStore(&grid_rw[counts + b], 0u);
        start = start + count;
    }
    if (t == 255u) {
        atomicStore(&grid_rw[starts + n], start);
    }
}

@compute @workgroup_size(256)
fn cells_scan(@builtin(local_invocation_index) t: u32) {
    let buckets = P.counts.w;
    scan(t, buckets, 0u, buckets, 2u * buckets + 1u);
}

// Cell g into the buckets of the grid cells its box overlaps (in any order; cells_sort orders
// them). An entry past the room for them is left out, and the status says so.
@compute @workgroup_size(64)
fn cells_scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let g = point_index(gid, groups);
    if (g >= P.contact.y) {
        return;
    }
    let bx = cell_box(g);
    if (bx.hi.x < bx.lo.x) {
        return;
    }
    let i0 = vec3<i32>(grid_cell_of(bx.lo));
    let span = vec3<u32>(vec3<i32>(grid_cell_of(bx.hi)) - i0);
    let cursors = 2u * P.counts.w + 1u;
    for (var x = 0u; x <= span.x; x = x + 1u) {
        for (var y = 0u; y <= span.y; y = y + 1u) {
            for (var z = 0u; z <= span.z; z = z + 1u) {
                let key = i0 + vec3<i32>(vec3<u32>(x, y, z));
                let slot = atomicAdd(&grid_rw[cursors + bucket_of(key)], 1u);
                if (slot < P.contact.z) {
                    atomicStore(&grid_rw[P.grid_at.x + slot], g);
                } else {
                    atomicOr(&status[5], 1u);
                }
            }
        }
    }
}

// Sorts the entries in [lo, hi) of the contact buffer (insertion sort: a list holds a few).
fn sort_range(lo: u32, hi: u32) {
    for (var s = lo + 1u; s < hi; s = s + 1u) {
        let e = atomicLoad(&grid_rw[s]);
        var t = s;
        while (t > lo && atomicLoad(&grid_rw[t - 1u]) > e) {
            atomicStore(&grid_rw[t], atomicLoad(&grid_rw[t - 1u]));
            t = t - 1u;
        }
        atomicStore(&grid_rw[t], e);
    }
}

// Sorts bucket b's entries by cell.
@compute @workgroup_size(64)
fn cells_sort(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let b = point_index(gid, groups);
    let buckets = P.counts.w;
    if (b >= buckets) {
        return;
    }
    let room = P.contact.z;
    let lo = min(atomicLoad(&grid_rw[buckets + b]), room);
    let hi = min(atomicLoad(&grid_rw[buckets + b + 1u]), room);
    sort_range(P.grid_at.x + lo, P.grid_at.x + hi);
}

// Where a point is in a cell: its place (u, v, w) and the rows of the inverse of the cell map's
// derivative there (to turn gradients over (u, v, w) into gradients in space); `found` false
// when it is not in the cell or the cell is degenerate there.
struct Located {
    found: bool,
    uvw: vec3<f32>,
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
}

// The rows of the inverse of the matrix with columns c0, c1, c2 (w 0: singular).
struct Inverse {
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
    ok: bool,
}

fn inverse_columns(c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>) -> Inverse {
    let r0 = cross(c1, c2);
    let r1 = cross(c2, c0);
    let r2 = cross(c0, c1);
    let det = dot(c0, r0);
    if (!(abs(det) > 1e-30) || not_finite(det)) {
        return Inverse(r0, r1, r2, false);
    }
    return Inverse(r0 / det, r1 / det, r2 / det, true);
}

// The inverse of the cell map's derivative at uvw (columns ∂x/∂u, ∂x/∂v, ∂x/∂w).
fn cell_inverse(c: array<vec3<f32>, 8>, uvw: vec3<f32>) -> Inverse {
    var j0 = vec3<f32>(0.0);
    var j1 = vec3<f32>(0.0);
    var j2 = vec3<f32>(0.0);
    for (var k = 0u; k < 8u; k = k + 1u) {
        let d = corner_weight_derivative(k, uvw);
        j0 = j0 + c[k] * d.x;
        j1 = j1 + c[k] * d.y;
        j2 = j2 + c[k] * d.z;
    }
    return inverse_columns(j0, j1, j2);
}

fn cell_map(c: array<vec3<f32>, 8>, uvw: vec3<f32>) -> vec3<f32> {
    var x = vec3<f32>(0.0);
    for (var k = 0u; k < 8u; k = k + 1u) {
        x = x + c[k] * corner_weight(k, uvw);
    }
    return x;
}

// Newton iterations at most (the core's MAX_LOCATE).
const MAX_LOCATE: u32 = 16u;

// Where p is in the cell of corners c (the core's `locate`), in f32: Newton's method from the
// middle until the residual is within f32's rounding of the cell's and p's coordinates, then
// one more step; inside when (u, v, w) is in [0, 1]³ within that rounding (the core: 1e-9).
fn locate(c: array<vec3<f32>, 8>, p: vec3<f32>) -> Located {
    let none = Located(false, vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    let size = length(c[7] - c[0]) + length(c[6] - c[1]);
    let scale = size + max(max(abs(p.x), abs(p.y)), abs(p.z));
    let tolerance = 1e-5 * scale;
    let slack = 4e-6 * scale / size;
    var uvw = vec3<f32>(0.5);
    var converged = false;
    for (var it = 0u; it < MAX_LOCATE; it = it + 1u) {
        let r = p - cell_map(c, uvw);
        let inverse = cell_inverse(c, uvw);
        if (!inverse.ok) {
            return none;
        }
        uvw = uvw + vec3<f32>(dot(inverse.r0, r), dot(inverse.r1, r), dot(inverse.r2, r));
        if (length(r) <= tolerance) {
            // That step was the last.
            converged = true;
            break;
        }
        // Far outside the cell: not in it (Newton's method may wander off there).
        if (!(all(uvw >= vec3<f32>(-1.0 - slack)) && all(uvw <= vec3<f32>(2.0 + slack)))) {
            return none;
        }
    }
    if (!converged || !(all(uvw >= vec3<f32>(-slack)) && all(uvw <= vec3<f32>(1.0 + slack)))) {
        return none;
    }
    uvw = clamp(uvw, vec3<f32>(-slack), vec3<f32>(1.0 + slack));
    let rows = cell_inverse(c, uvw);
    if (!rows.ok) {
        return none;
    }
    return Located(true, uvw, rows.r0, rows.r1, rows.r2);
}

// The interpolated signed distance of cell g at its place uvw (w), and its gradient over (u, v,
// w) (xyz): trilinear on the sub-cell of the grid `refine` times as fine that holds uvw (the
// core's `distance_in`).
fn distance_in(g: u32, uvw: vec3<f32>) -> vec4<f32> {
    let record = scene[P.contact_at.y + g];
    let ry = record.z & ((1u << REFINE_SHIFT) - 1u);
    let refine = f32(record.z >> REFINE_SHIFT);
    let rz = record.w;
    let sub = clamp(floor(uvw * refine), vec3<f32>(0.0), vec3<f32>(refine - 1.0));
    let t = uvw * refine - sub;
    let s = vec3<u32>(sub);
    let base = record.y + (s.x * ry + s.y) * rz + s.z;
    var phi = 0.0;
    var gradient = vec3<f32>(0.0);
    for (var k = 0u; k < 8u; k = k + 1u) {
        let d = bitcast<f32>(scene_word(base + ((k >> 2u) * ry + ((k >> 1u) & 1u)) * rz + (k & 1u)));
        phi = phi + d * corner_weight(k, t);
        gradient = gradient + d * corner_weight_derivative(k, t) * refine;
    }
    return vec4<f32>(gradient, phi);
}

// The force on a sample `depth` inside another body whose outward normal is n, moving at w
// relative to it (the core's touch_force): the penalty spring and damper along n, Coulomb
// friction across it (FRICTION) capped at c_max·|w across n|.
fn touch_force(n: vec3<f32>, w: vec3<f32>, depth: f32, c_max: f32) -> vec3<f32> {
    if (!(depth > 0.0)) {
        return vec3<f32>(0.0);
    }
    let normal = P.law.y * depth;
    var f = n * (normal - P.law.z * dot(w, n));
    if (FRICTION) {
        f = f + sliding(n, w, P.law.w * normal, c_max);
    }
    return f;
}

// Sample s: where it is (its cell's corners' trilinear interpolation), whether it is inside a
// cell of another body below that body's surface there (the first in its grid cell's bucket
// that holds it so decides, as on the core; a cell holding it outside its body's surface passes
// the search on to other bodies' cells), and if so its force, into its record; counted in the
// touches of that cell.
@compute @workgroup_size(64)
fn touch(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = point_index(gid, groups);
    if (s >= P.contact.x) {
        return;
    }
    let sample = scene[P.contact_at.x + s];
    let corner = sample.x;
    let local = bitcast<vec3<f32>>(sample.yzw);
    let a = points[corner].y & BODY_BITS;
    var ps = vec3<f32>(0.0);
    var w = vec3<f32>(0.0);
    for (var k = 0u; k < 8u; k = k + 1u) {
        let q = corner + corner_offset(a, k);
        let wk = corner_weight(k, local);
        ps = ps + position(q) * wk;
        w = w + velocity(q) * wk;
    }
    let r = record_at(s);
    var force = vec3<f32>(0.0);
    var touched = NONE;
    var uvw = vec3<f32>(0.0);
    let bucket = bucket_of(vec3<i32>(grid_cell_of(ps)));
    let room = P.contact.z;
    let lo = min(atomicLoad(&grid_rw[P.counts.w + bucket]), room);
    let hi = min(atomicLoad(&grid_rw[P.counts.w + bucket + 1u]), room);
    var previous = NONE;
    // The body last found to hold the sample in a cell but outside its surface.
    var clear_of = NONE;
    for (var e = lo; e < hi; e = e + 1u) {
        // The bucket's cells in order, each once (a cell is in a bucket once per grid cell of
        // its box that hashes there; the sample is in its box only if its grid cell is one).
        let g = atomicLoad(&grid_rw[P.grid_at.x + e]);
        if (g == previous) {
            continue;
        }
        previous = g;
        let bx = cell_box(g);
        if (!(all(ps >= bx.lo) && all(ps <= bx.hi))) {
            continue;
        }
        let cb = cell_corner(g);
        let b = points[cb].y & BODY_BITS;
        if (b == a || b == clear_of) {
            continue;
        }
        var corners: array<vec3<f32>, 8>;
        for (var k = 0u; k < 8u; k = k + 1u) {
            corners[k] = position(cb + corner_offset(b, k));
        }
        let at = locate(corners, ps);
        if (!at.found) {
            continue;
        }
        // The first cell that holds the sample inside its body's surface decides; one holding it
        // outside does not (its body's other cells hold it only on a shared face, with the same
        // distance, but another body's may hold it inside).
        let d = distance_in(g, at.uvw);
        let gradient = at.r0 * d.x + at.r1 * d.y + at.r2 * d.z;
        let l = length(gradient);
        if (d.w < 0.0 && l > 0.0) {
            // The core's contact::bodies::MIN_GRADIENT: at a sharp edge the gradient vanishes
            // with the distance.
            let depth = -d.w / max(l, 0.5);
            let n = gradient / l;
            // The velocity relative to the other body's cell there.
            for (var k = 0u; k < 8u; k = k + 1u) {
                w = w + velocity(cb + corner_offset(b, k)) * -corner_weight(k, at.uvw);
            }
            var c_max = 0.0;
            if (FRICTION) {
                let ma = P.bodies[a].material.x;
                let mb = P.bodies[b].material.x;
                c_max = ma * mb / (ma + mb) / P.law.x;
            }
            force = touch_force(n, w, depth, c_max);
            touched = g;
            uvw = at.uvw;
            atomicAdd(&grid_rw[P.grid_at.z + g], 1u);
            break;
        }
        clear_of = b;
    }
    store_f(r, force.x);
    store_f(r + 1u, force.y);
    store_f(r + 2u, force.z);
    atomicStore(&grid_rw[r + 3u], touched);
    store_f(r + 4u, uvw.x);
    store_f(r + 5u, uvw.y);
    store_f(r + 6u, uvw.z);
}

@compute @workgroup_size(256)
fn touches_scan(@builtin(local_invocation_index) t: u32) {
    scan(t, P.contact.y, P.grid_at.z, P.grid_at.w, P.grid_at2.x);
}

// Sample s, if it touches, into its cell's list (in any order; touches_sort orders them).
@compute @workgroup_size(64)
fn touches_scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = point_index(gid, groups);
    if (s >= P.contact.x) {
        return;
    }
    let g = atomicLoad(&grid_rw[record_at(s) + 3u]);
    if (g == NONE) {
        return;
    }
    let slot = atomicAdd(&grid_rw[P.grid_at2.x + g], 1u);
    atomicStore(&grid_rw[P.grid_at2.y + slot], s);
}

// Sorts cell g's touches by sample.
@compute @workgroup_size(64)
fn touches_sort(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let g = point_index(gid, groups);
    if (g >= P.contact.y) {
        return;
    }
    let lo = atomicLoad(&grid_rw[P.grid_at.w + g]);
    let hi = atomicLoad(&grid_rw[P.grid_at.w + g + 1u]);
    sort_range(P.grid_at2.y + lo, P.grid_at2.y + hi);
}
