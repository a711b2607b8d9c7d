// The entry points: one stage of an integrator per dispatch (see model.wgsl), the last one
// placing the pins on paths; after a step, the friction anchors' update and the pin table's
// next row.

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

struct End {
    p: vec3<f32>,
    v: vec3<f32>,
}

// Point i's step integrated to (p, v), as the core accepts it: checked as integrated; then,
// when it is sound, a pin on a path put where its path says at the step's end, at the path's
// velocity (a point at fault keeps what was integrated, which the blow-up report reads, as the
// core's does), and its depth recorded there. The core moves such a pin from the step's start
// by the path's change of offset over the step; from its origin on the path (its position less
// the path's offset when it was loaded) to the path's offset now is the same place, without
// the f32 rounding of every step adding up.
fn step_end(i: u32, p: vec3<f32>, v: vec3<f32>) -> End {
    var end = End(p, v);
    if (!sound(i, p, v)) {
        return end;
    }
    if (PINS) {
        let on_path = scene[P.pins.x + i];
        if (on_path.w != NONE) {
            let at = P.pins.y + atomicLoad(&status[3]) + 2u * on_path.w;
            end = End(bitcast<vec3<f32>>(on_path.xyz) + scene_f(at).xyz, scene_f(at + 1u).xyz);
        }
    }
    record_depth(i, end.p);
    return end;
}

// RK4 stage 1: k1 at y (in `state_in`, the step's start); the sums start with it, and
// `state_out` gets y + dt/2·k1.
@compute @workgroup_size(64)
fn rk4_1(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let p = state_in[2u * i].xyz;
    let v = state_in[2u * i + 1u].xyz;
    let h = 0.5 * P.law.x;
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
    if (i >= P.counts.x) {
        return;
    }
    rk4_middle(i, 0.5 * P.law.x);
}

@compute @workgroup_size(64)
fn rk4_3(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    rk4_middle(i, P.law.x);
}

// RK4 stage 4: k4 at the stage in `state_in`; the step's end, y + dt/6·(k1 + 2k2 + 2k3 + k4),
// checked, replaces the start in `base`.
@compute @workgroup_size(64)
fn rk4_4(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let sv = state_in[2u * i + 1u].xyz;
    let w = P.law.x / 6.0;
    let p = base[2u * i].xyz + (sums[2u * i].xyz + sv) * w;
    let v = base[2u * i + 1u].xyz + (sums[2u * i + 1u].xyz + a) * w;
    let end = step_end(i, p, v);
    write_base(i, end.p, end.v);
}

// RK2 (midpoint), first stage: `state_out` gets y + dt/2·f(y).
@compute @workgroup_size(64)
fn rk2_1(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let p = state_in[2u * i].xyz;
    let v = state_in[2u * i + 1u].xyz;
    let h = 0.5 * P.law.x;
    write_out(i, p + v * h, v + a * h);
}

// RK2, second stage: the slope at the midpoint in `state_in` moves the start in `base` by dt.
@compute @workgroup_size(64)
fn rk2_2(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let sv = state_in[2u * i + 1u].xyz;
    let dt = P.law.x;
    let p = base[2u * i].xyz + sv * dt;
    let v = base[2u * i + 1u].xyz + a * dt;
    let end = step_end(i, p, v);
    write_base(i, end.p, end.v);
}

// Euler: the position moves with the old velocity, the velocity with the acceleration; into
// `state_out` (the next step reads it).
@compute @workgroup_size(64)
fn euler(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let dt = P.law.x;
    let p = state_in[2u * i].xyz + state_in[2u * i + 1u].xyz * dt;
    let v = state_in[2u * i + 1u].xyz + a * dt;
    let end = step_end(i, p, v);
    write_out(i, end.p, end.v);
}

// Symplectic Euler: the velocity first, then the position with the new velocity.
@compute @workgroup_size(64)
fn symplectic(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let a = acceleration(i);
    let dt = P.law.x;
    let v = state_in[2u * i + 1u].xyz + a * dt;
    let p = state_in[2u * i].xyz + v * dt;
    let end = step_end(i, p, v);
    write_out(i, end.p, end.v);
}

// After a step, with the step's end in `state_in` (the core's friction::Anchors::update): a
// point that left an obstacle lets go; one that touches it and is not tied is tied where it is;
// one whose offset from its anchor across the normal is past the Coulomb cone (μ·depth) drags
// the anchor along to the cone's edge.
@compute @workgroup_size(64)
fn anchors(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(gid, groups);
    if (i >= P.counts.x) {
        return;
    }
    let p = position(i);
    var obstacles = 0u;
    if (FRICTION) {
        obstacles = P.counts.z;
    }
    // The point's clearance, from scene_rw as the obstacles below.
    var out: f32 = 0.0;
    if (CLEARANCE) {
        out = bitcast<vec4<f32>>(scene_rw[P.field_res.y + i / 4u])[i % 4u];
    }
    for (var o = 0u; o < obstacles; o = o + 1u) {
        let at = anchor_at(o, i);
        // The obstacles from scene_rw: this pass may not bind the scene read-only as well.
        let shape = P.at.x + 3u * o;
        var c = shape_depth(scene_rw[shape].x, bitcast<vec4<f32>>(scene_rw[shape + 1u]),
            bitcast<vec4<f32>>(scene_rw[shape + 2u]), p);
        c.w = c.w - out;
        if (!(c.w > 0.0)) {
            scene_rw[at] = vec4<u32>(0u);
            continue;
        }
        let anchor = bitcast<vec4<f32>>(scene_rw[at]);
        if (anchor.w == 0.0) {
            scene_rw[at] = bitcast<vec4<u32>>(vec4<f32>(p, 1.0));
            continue;
        }
        let offset = across(p - anchor.xyz, c.xyz);
        let size = length(offset);
        let reach = P.law.w * c.w;
        if (size > reach) {
            scene_rw[at] = bitcast<vec4<u32>>(vec4<f32>(p - offset * (reach / size), 1.0));
        }
    }
    if (WALL_FRICTION) {
        wall_anchors(i, p, out);
    }
}

// The walls' and the classic plane's anchors, after the obstacles' (WALL_FRICTION), by the same
// rule with their own coefficient; `out` is the point's clearance.
fn wall_anchors(i: u32, p: vec3<f32>, out: f32) {
    var walls = 6u;
    if (CLASSIC_PLANE) {
        walls = 7u;
    }
    for (var w = 0u; w < walls; w = w + 1u) {
        let at = anchor_at(wall_slot(w), i);
        var c = wall_contact(w, p);
        c.w = c.w - out;
        if (!(c.w > 0.0)) {
            scene_rw[at] = vec4<u32>(0u);
            continue;
        }
        let anchor = bitcast<vec4<f32>>(scene_rw[at]);
        if (anchor.w == 0.0) {
            scene_rw[at] = bitcast<vec4<u32>>(vec4<f32>(p, 1.0));
            continue;
        }
        let offset = across(p - anchor.xyz, c.xyz);
        let size = length(offset);
        let reach = P.flags.y * c.w;
        if (size > reach) {
            scene_rw[at] = bitcast<vec4<u32>>(vec4<f32>(p - offset * (reach / size), 1.0));
        }
    }
}

// After each step of a model with pins on paths (one thread): the next step reads the pin
// table's next row.
@compute @workgroup_size(1)
fn pins_next() {
    atomicAdd(&status[3], P.pins.z);
}
