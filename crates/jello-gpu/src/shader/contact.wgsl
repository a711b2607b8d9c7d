// Contacts between bodies, surface to surface (the core's contact::bodies), in f32: what the
// layouts are and what the force passes read. Each body's contact surface is in `scene`:
//
// - per body, its cells' eight corners as flat offsets from the lower corner (two vec4, in the
//   order of the core's CORNERS: corner k is (k >> 2, k >> 1 & 1, k & 1));
// - the signed distances at rest (f32 words), body after body, each on a grid `refine` times as
//   fine as its lattice (the core's ContactSurface::refine: 4, or 8 for a skin that needs it);
// - the kept cells of every body in order, one vec4 each: [lower corner (model index), where its
//   block of distances starts (word), the distance grid's points along y (low 24 bits) and its
//   refinement (high 8 bits), its points along z];
// - the samples of every body in order, one vec4 each: [lower corner of its cell (model index),
//   its place (u, v, w) in the cell (f32)];
// - per point, the sample corners it is (8 · sample + corner: the sample's force goes to it by
//   the corner's weight) and the cell corners it is (8 · cell + corner), each list as starts
//   (points + 1 words) then entries, ordered by sample (cell), then corner.
//
// Before every force pass, the passes of touch.wgsl find every sample's touch, into a record per
// sample in the contact buffer (`grid`): [its force (N), the cell of the other body it is in
// (NONE: it touches nothing)], [its place (u, v, w) in that cell, 0]; and list the touches in each
// cell, in the samples' order. A point's contact force is then a gather (`contacts_on`).

// Where the third word of a cell record splits: the distance grid's points along y below, its
// refinement from here up (packing.rs's REFINE_SHIFT).
const REFINE_SHIFT: u32 = 24u;

// Word `w` of the scene.
fn scene_word(w: u32) -> u32 {
    return scene[w >> 2u][w & 3u];
}

// The trilinear weight of corner k of a cell at its place t (the core's `weights`).
fn corner_weight(k: u32, t: vec3<f32>) -> f32 {
    let fu = select(1.0 - t.x, t.x, (k & 4u) != 0u);
    let fv = select(1.0 - t.y, t.y, (k & 2u) != 0u);
    let fw = select(1.0 - t.z, t.z, (k & 1u) != 0u);
    return fu * fv * fw;
}

// The derivatives of corner k's weight along u, v and w (the core's `weight_derivatives`).
fn corner_weight_derivative(k: u32, t: vec3<f32>) -> vec3<f32> {
    let fu = select(1.0 - t.x, t.x, (k & 4u) != 0u);
    let fv = select(1.0 - t.y, t.y, (k & 2u) != 0u);
    let fw = select(1.0 - t.z, t.z, (k & 1u) != 0u);
    let du = select(-1.0, 1.0, (k & 4u) != 0u);
    let dv = select(-1.0, 1.0, (k & 2u) != 0u);
    let dw = select(-1.0, 1.0, (k & 1u) != 0u);
    return vec3<f32>(du * fv * fw, fu * dv * fw, fu * fv * dw);
}

// The flat offset of corner k of body b's cells from their lower corner.
fn corner_offset(b: u32, k: u32) -> u32 {
    return scene[P.contact_at.z + 2u * b + (k >> 2u)][k & 3u];
}

// Where sample s's record starts in the contact buffer (words).
fn record_at(s: u32) -> u32 {
    return P.grid_at2.z + 8u * s;
}

// The contact force on point i: over the samples it is a corner of, which touch another body, +f
// by its weight at the sample; over the touches in the cells of its body it is a corner of, −f
// by its weight at the touch; in the order of the samples, as the core sums them (a point is
// never both for one sample: the other body's cell is not its own).
fn contacts_on(i: u32) -> vec3<f32> {
    var f = vec3<f32>(0.0);
    var s_at = scene_word(P.gather_at.x + i);
    let s_end = scene_word(P.gather_at.x + i + 1u);
    let c_first = scene_word(P.gather_at.z + i);
    let cells = scene_word(P.gather_at.z + i + 1u) - c_first;
    // Each cell's touches, in the samples' order.
    var at: array<u32, 8>;
    var end: array<u32, 8>;
    for (var j = 0u; j < cells; j = j + 1u) {
        let g = scene_word(P.gather_at.w + c_first + j) >> 3u;
        at[j] = grid[P.grid_at.w + g];
        end[j] = grid[P.grid_at.w + g + 1u];
    }
    loop {
        // The next sample: its own (corner) first, else the lowest in the cells' lists.
        var next = NONE;
        var src = 8u;
        if (s_at < s_end) {
            next = scene_word(P.gather_at.y + s_at) >> 3u;
        }
        for (var j = 0u; j < cells; j = j + 1u) {
            if (at[j] < end[j]) {
                let s = grid[P.grid_at2.y + at[j]];
                if (s < next) {
                    next = s;
                    src = j;
                }
            }
        }
        if (next == NONE) {
            break;
        }
        let r = record_at(next);
        let force = vec3<f32>(bitcast<f32>(grid[r]), bitcast<f32>(grid[r + 1u]), bitcast<f32>(grid[r + 2u]));
        if (src == 8u) {
            let k = scene_word(P.gather_at.y + s_at) & 7u;
            s_at = s_at + 1u;
            if (grid[r + 3u] != NONE) {
                let local = bitcast<vec3<f32>>(scene[P.contact_at.x + next].yzw);
                f = f + force * corner_weight(k, local);
            }
        } else {
            let k = scene_word(P.gather_at.w + c_first + src) & 7u;
            at[src] = at[src] + 1u;
            let uvw = vec3<f32>(bitcast<f32>(grid[r + 4u]), bitcast<f32>(grid[r + 5u]), bitcast<f32>(grid[r + 6u]));
            f = f + force * -corner_weight(k, uvw);
        }
    }
    return f;
}
