// The check of a step's end, shared by step.wgsl and resident.wgsl.

fn not_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) == 0x7f800000u;
}

// A step's end state is sound when every number is finite and the point is no further outside
// the box than the escape margin (the CPU core's rule); a point at fault is recorded in the
// status.
fn sound(i: u32, p: vec3<f32>, v: vec3<f32>) -> bool {
    let m = P.flags.x;
    let lo = P.box_lo.xyz - vec3<f32>(m);
    let hi = P.box_hi.xyz + vec3<f32>(m);
    let inside = all(p >= lo) && all(p <= hi);
    let bad = !inside || not_finite(p.x) || not_finite(p.y) || not_finite(p.z)
        || not_finite(v.x) || not_finite(v.y) || not_finite(v.z);
    if (bad) {
        atomicOr(&status[0], 1u);
        atomicMin(&status[1], i);
    }
    return !bad;
}

// Records how deep point i, at p at a step's end, is into a wall (the furthest it is outside on
// any axis), the plane or an obstacle, less its clearance. A point outside its body (a
// lattice's corner beyond a mesh) is in no contact, as in the core's max_penetration.
fn record_depth(i: u32, p: vec3<f32>) {
    if ((points[i].y & ACTIVE) == 0u) {
        return;
    }
    var depth = max(max(max(P.box_lo.x - p.x, p.x - P.box_hi.x), max(P.box_lo.y - p.y, p.y - P.box_hi.y)),
        max(max(P.box_lo.z - p.z, p.z - P.box_hi.z), 0.0));
    if (CLASSIC_PLANE) {
        depth = max(depth, plane_depth(p));
    }
    if (OBSTACLES) {
        for (var o = 0u; o < P.counts.z; o = o + 1u) {
            depth = max(depth, obstacle_depth(o, p).w);
        }
    }
    depth = depth - clearance(i);
    if (depth > 0.0) {
        atomicMax(&status[2], bitcast<u32>(depth));
    }
}
