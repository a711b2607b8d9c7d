// Jello's explicit integrators on the GPU, in f32: one thread per lattice point gathers the forces
// of its up to 32 springs (the 16 stencil entries of SPEC.md, forward and backward), the field,
// walls, plane, control force and gravity, and applies one stage of its integrator. Each spring is
// evaluated at both its ends (a gather needs no atomics, so it is deterministic).
//
// The state buffers hold two vec4 per point: position (w unused), velocity (w unused).
// Every entry point reads the stage it evaluates from `state_in` and writes its own point only,
// so a dispatch never reads what it writes.

struct Params {
    // nx, ny, nz, points
    dims: vec4<u32>,
    // Per stencil entry s (vec4 s / 4, component s % 4): flat offset to the neighbour, rest
    // length (m), stiffness (N/m), damping (N·s/m).
    offsets: array<vec4<i32>, 4>,
    rest: array<vec4<f32>, 4>,
    stiff: array<vec4<f32>, 4>,
    damp: array<vec4<f32>, 4>,
    // mass (kg), dt (s), kCollision, dCollision
    material: vec4<f32>,
    // escape margin (m), field present, plane present, per-spring values present
    flags: vec4<f32>,
    box_lo: vec4<f32>,
    box_hi: vec4<f32>,
    // a, b, c, d of the plane; then |(a, b, c)| and the allowed side (±1)
    plane: vec4<f32>,
    plane_side: vec4<f32>,
    gravity: vec4<f32>,
    field_lo: vec4<f32>,
    field_hi: vec4<f32>,
    // res, 0, 0, 0
    field_res: vec4<u32>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> state_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> base: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state_out: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> sums: array<vec4<f32>>;
// Per point: bit s set when the spring to the neighbour at +offset[s] exists, bit 16 + s when
// the one to the neighbour at −offset[s] does.
@group(0) @binding(5) var<storage, read> links: array<u32>;
// Per point: the control force (N) in xyz, and w = 1 for a point that moves, 0 for one pinned
// or unused (it does not accelerate).
@group(0) @binding(6) var<storage, read> extra: array<vec4<f32>>;
// res³ node forces (N), i outermost, k innermost; one unused node when there is no field.
@group(0) @binding(7) var<storage, read> field: array<vec4<f32>>;
// A body with per-spring values: for point p and stencil entry s, at 16 p + s, the rest length,
// stiffness and damping of the spring from p to its neighbour at +offset[s] (one unused element
// otherwise).
@group(0) @binding(9) var<storage, read> springs: array<vec4<f32>>;
// [0]: 1 once a step ended unsound; [1]: the lowest point found at fault; [2]: the deepest
// penetration into a wall or the plane at a step's end (m, the bits of a non-negative f32).
@group(0) @binding(8) var<storage, read_write> status: array<atomic<u32>>;

const WORKGROUP: u32 = 64u;

fn point_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * WORKGROUP;
}

// Force on a point at p with velocity v from the spring to point j.
fn spring(p: vec3<f32>, v: vec3<f32>, j: u32, rest: f32, k: f32, d: f32) -> vec3<f32> {
    let q = state_in[2u * j].xyz;
    let w = state_in[2u * j + 1u].xyz;
    let l_vec = p - q;
    let l2 = dot(l_vec, l_vec);
    if (l2 <= 0.0) {
        return vec3<f32>(0.0);
    }
    let inv = inverseSqrt(l2);
    let l = l2 * inv;
    let closing = dot(v - w, l_vec) * inv;
    return l_vec * ((-k * (l - rest) - d * closing) * inv);
}

fn cell(c: f32, lo: f32, hi: f32, cells: f32) -> vec2<f32> {
    let u = (c - lo) / (hi - lo) * cells;
    let i = clamp(floor(u), 0.0, cells - 1.0);
    return vec2<f32>(i, u - i);
}

fn node(i: u32, j: u32, k: u32) -> vec3<f32> {
    let r = P.field_res.x;
    return field[(i * r + j) * r + k].xyz;
}

// The force field at p: trilinear interpolation of its cell, p clamped into the field's box.
fn field_force(p: vec3<f32>) -> vec3<f32> {
    let lo = P.field_lo.xyz;
    let hi = P.field_hi.xyz;
    let q = clamp(p, lo, hi);
    let cells = f32(P.field_res.x - 1u);
    let cx = cell(q.x, lo.x, hi.x, cells);
    let cy = cell(q.y, lo.y, hi.y, cells);
    let cz = cell(q.z, lo.z, hi.z, cells);
    let i = u32(cx.x);
    let j = u32(cy.x);
    let k = u32(cz.x);
    let c00 = mix(node(i, j, k), node(i, j, k + 1u), cz.y);
    let c01 = mix(node(i, j + 1u, k), node(i, j + 1u, k + 1u), cz.y);
    let c10 = mix(node(i + 1u, j, k), node(i + 1u, j, k + 1u), cz.y);
    let c11 = mix(node(i + 1u, j + 1u, k), node(i + 1u, j + 1u, k + 1u), cz.y);
    return mix(mix(c00, c01, cy.y), mix(c10, c11, cy.y), cx.y);
}

fn wall(c: f32, v: f32, lo: f32, hi: f32, kc: f32, dc: f32) -> f32 {
    if (c < lo) {
        return kc * (lo - c) - dc * v;
    }
    if (c > hi) {
        return -(kc * (c - hi)) - dc * v;
    }
    return 0.0;
}

// Acceleration of point i at the stage in `state_in` (SPEC.md's forces over the mass, plus
// gravity); zero for a point that does not move.
fn acceleration(i: u32) -> vec3<f32> {
    let p = state_in[2u * i].xyz;
    let v = state_in[2u * i + 1u].xyz;
    let bits = links[i];
    var f = vec3<f32>(0.0);
    let own_values = P.flags.w != 0.0;
    for (var s = 0u; s < 16u; s = s + 1u) {
        let e = s / 4u;
        let c = s % 4u;
        let off = P.offsets[e][c];
        var values = vec3<f32>(P.rest[e][c], P.stiff[e][c], P.damp[e][c]);
        if (((bits >> s) & 1u) != 0u) {
            if (own_values) {
                values = springs[16u * i + s].xyz;
            }
            f = f + spring(p, v, u32(i32(i) + off), values.x, values.y, values.z);
        }
        if (((bits >> (s + 16u)) & 1u) != 0u) {
            let j = u32(i32(i) - off);
            if (own_values) {
                values = springs[16u * j + s].xyz;
            }
            f = f + spring(p, v, j, values.x, values.y, values.z);
        }
    }
    if (P.flags.y != 0.0) {
        f = f + field_force(p);
    }
    let kc = P.material.z;
    let dc = P.material.w;
    f.x = f.x + wall(p.x, v.x, P.box_lo.x, P.box_hi.x, kc, dc);
    f.y = f.y + wall(p.y, v.y, P.box_lo.y, P.box_hi.y, kc, dc);
    f.z = f.z + wall(p.z, v.z, P.box_lo.z, P.box_hi.z, kc, dc);
    if (P.flags.z != 0.0) {
        let s = dot(P.plane.xyz, p) + P.plane.w;
        let n = P.plane.xyz * (P.plane_side.y / P.plane_side.x);
        if (s * P.plane_side.y < 0.0) {
            let depth = abs(s) / P.plane_side.x;
            f = f + n * (kc * depth) - n * (dc * dot(v, n));
        }
    }
    let x = extra[i];
    f = f + x.xyz;
    // x.w: 1 for a point that moves, 0 for a pinned one, -1 for one outside the body.
    return (f / P.material.x + P.gravity.xyz) * max(x.w, 0.0);
}

// Point i's position and velocity into the stage written.
fn write_out(i: u32, p: vec3<f32>, v: vec3<f32>) {
    state_out[2u * i] = vec4<f32>(p, 0.0);
    state_out[2u * i + 1u] = vec4<f32>(v, 0.0);
}

// Point i's position and velocity at the step's end, over its start.
fn write_base(i: u32, p: vec3<f32>, v: vec3<f32>) {
    base[2u * i] = vec4<f32>(p, 0.0);
    base[2u * i + 1u] = vec4<f32>(v, 0.0);
}

fn not_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) == 0x7f800000u;
}

// A step's end state is sound when every number is finite and the point is no further outside
// the box than the escape margin (the CPU core's rule).
fn check(i: u32, p: vec3<f32>, v: vec3<f32>) {
    let m = P.flags.x;
    let lo = P.box_lo.xyz - vec3<f32>(m);
    let hi = P.box_hi.xyz + vec3<f32>(m);
    let inside = all(p >= lo) && all(p <= hi);
    let bad = !inside || not_finite(p.x) || not_finite(p.y) || not_finite(p.z)
        || not_finite(v.x) || not_finite(v.y) || not_finite(v.z);
    if (bad) {
        atomicOr(&status[0], 1u);
        atomicMin(&status[1], i);
        return;
    }
    // A point outside the body (a lattice's corner beyond a mesh) is in no contact, as in the
    // core's max_penetration.
    if (extra[i].w < 0.0) {
        return;
    }
    // How deep the point is into a wall (the furthest it is outside on any axis) or the plane.
    var depth = max(max(max(P.box_lo.x - p.x, p.x - P.box_hi.x), max(P.box_lo.y - p.y, p.y - P.box_hi.y)),
        max(max(P.box_lo.z - p.z, p.z - P.box_hi.z), 0.0));
    if (P.flags.z != 0.0) {
        let s = dot(P.plane.xyz, p) + P.plane.w;
        if (s * P.plane_side.y < 0.0) {
            depth = max(depth, abs(s) / P.plane_side.x);
        }
    }
    if (depth > 0.0) {
        atomicMax(&status[2], bitcast<u32>(depth));
    }
}

// RK4 stage 1: k1 at y (in `state_in`, the step's start); the sums start with it, and
// `state_out` gets y + dt/2·k1.
@compute @workgroup_size(64)
fn rk4_1(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let p = state_in[2u * i].xyz;
    let v = state_in[2u * i + 1u].xyz;
    let h = 0.5 * P.material.y;
    sums[2u * i] = vec4<f32>(v, 0.0);
    sums[2u * i + 1u] = vec4<f32>(a, 0.0);
    write_out(i, p + v * h, v + a * h);
}

// RK4 stages 2 and 3: k at the stage in `state_in`, added twice to the sums; `state_out` gets
// y + h·k with y the step's start in `base`.
fn rk4_middle(i: u32, h: f32) {
    let a = acceleration(i);
    let sv = state_in[2u * i + 1u].xyz;
    sums[2u * i] = vec4<f32>(sums[2u * i].xyz + sv * 2.0, 0.0);
    sums[2u * i + 1u] = vec4<f32>(sums[2u * i + 1u].xyz + a * 2.0, 0.0);
    write_out(i, base[2u * i].xyz + sv * h, base[2u * i + 1u].xyz + a * h);
}

@compute @workgroup_size(64)
fn rk4_2(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    rk4_middle(i, 0.5 * P.material.y);
}

@compute @workgroup_size(64)
fn rk4_3(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    rk4_middle(i, P.material.y);
}

// RK4 stage 4: k4 at the stage in `state_in`; the step's end, y + dt/6·(k1 + 2k2 + 2k3 + k4),
// replaces the start in `base`, checked.
@compute @workgroup_size(64)
fn rk4_4(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let sv = state_in[2u * i + 1u].xyz;
    let w = P.material.y / 6.0;
    let p = base[2u * i].xyz + (sums[2u * i].xyz + sv) * w;
    let v = base[2u * i + 1u].xyz + (sums[2u * i + 1u].xyz + a) * w;
    write_base(i, p, v);
    check(i, p, v);
}

// RK2 (midpoint), first stage: `state_out` gets y + dt/2·f(y).
@compute @workgroup_size(64)
fn rk2_1(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let p = state_in[2u * i].xyz;
    let v = state_in[2u * i + 1u].xyz;
    let h = 0.5 * P.material.y;
    write_out(i, p + v * h, v + a * h);
}

// RK2, second stage: the slope at the midpoint in `state_in` moves the start in `base` by dt.
@compute @workgroup_size(64)
fn rk2_2(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let sv = state_in[2u * i + 1u].xyz;
    let dt = P.material.y;
    let p = base[2u * i].xyz + sv * dt;
    let v = base[2u * i + 1u].xyz + a * dt;
    write_base(i, p, v);
    check(i, p, v);
}

// Euler: the position moves with the old velocity, the velocity with the acceleration; into
// `state_out` (the next step reads it).
@compute @workgroup_size(64)
fn euler(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let dt = P.material.y;
    let p = state_in[2u * i].xyz + state_in[2u * i + 1u].xyz * dt;
    let v = state_in[2u * i + 1u].xyz + a * dt;
    write_out(i, p, v);
    check(i, p, v);
}

// Symplectic Euler: the velocity first, then the position with the new velocity.
@compute @workgroup_size(64)
fn symplectic(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.dims.w) {
        return;
    }
    let a = acceleration(i);
    let dt = P.material.y;
    let v = state_in[2u * i + 1u].xyz + a * dt;
    let p = state_in[2u * i].xyz + v * dt;
    write_out(i, p, v);
    check(i, p, v);
}
