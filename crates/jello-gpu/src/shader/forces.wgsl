// The forces on a point (SPEC.md's springs, walls and plane; the core's field, obstacles,
// friction, contacts between bodies and pulls), as the f64 core sums them, in f32.

// Force on a point at p with velocity v from the spring to point j.
fn spring(p: vec3<f32>, v: vec3<f32>, j: u32, rest: f32, k: f32, d: f32) -> vec3<f32> {
    let l_vec = p - position(j);
    let l2 = dot(l_vec, l_vec);
    if (l2 <= 0.0) {
        return vec3<f32>(0.0);
    }
    let inv = inverseSqrt(l2);
    let l = l2 * inv;
    let closing = dot(v - velocity(j), l_vec) * inv;
    return l_vec * ((-k * (l - rest) - d * closing) * inv);
}

// The springs of point i (of body b, with link bits `bits`). Called with a constant b for a
// model of one body (ONE_BODY), so that the stencil's values are constants of the uniform
// block.
fn springs_on(i: u32, p: vec3<f32>, v: vec3<f32>, bits: u32, b: u32) -> vec3<f32> {
    let table = P.bodies[b].index.y;
    let first = P.bodies[b].index.x;
    var f = vec3<f32>(0.0);
    for (var s = 0u; s < 16u; s = s + 1u) {
        let e = s / 4u;
        let c = s % 4u;
        let off = P.bodies[b].offsets[e][c];
        var values = vec3<f32>(P.bodies[b].rest[e][c], P.bodies[b].stiff[e][c], P.bodies[b].damp[e][c]);
        if (((bits >> s) & 1u) != 0u) {
            if (SPRING_VALUES && table != NONE) {
                values = scene_f(table + 16u * (i - first) + s).xyz;
            }
            f = f + spring(p, v, u32(i32(i) + off), values.x, values.y, values.z);
        }
        if (((bits >> (s + 16u)) & 1u) != 0u) {
            let j = u32(i32(i) - off);
            if (SPRING_VALUES && table != NONE) {
                values = scene_f(table + 16u * (j - first) + s).xyz;
            }
            f = f + spring(p, v, j, values.x, values.y, values.z);
        }
    }
    return f;
}

fn cell(c: f32, lo: f32, hi: f32, cells: f32) -> vec2<f32> {
    let u = (c - lo) / (hi - lo) * cells;
    let i = clamp(floor(u), 0.0, cells - 1.0);
    return vec2<f32>(i, u - i);
}

fn node(i: u32, j: u32, k: u32) -> vec3<f32> {
    let r = P.field_res.x;
    return scene_f(P.at.y + (i * r + j) * r + k).xyz;
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

// Depth (m) of the classic plane's contact with p (0 on the allowed side).
fn plane_depth(p: vec3<f32>) -> f32 {
    let s = dot(P.plane.xyz, p) + P.plane.w;
    if (s * P.plane_side.y < 0.0) {
        return abs(s) / P.plane_side.x;
    }
    return 0.0;
}

const PLANE: u32 = 0u;
const SPHERE: u32 = 1u;
const SOLID_BOX: u32 = 2u;

// The contact with p of an obstacle of `kind` and shape a, b: its depth (≤ 0 for none) in w and
// its outward unit normal in xyz. A plane's shape is [a, b, c, d], [|(a, b, c)|, allowed side,
// 0, 0]; a sphere's [centre, radius]; a solid box's [min], [max] (pushed out through the
// nearest face, ties to the first of −x, +x, −y, +y, −z, +z).
fn shape_depth(kind: u32, a: vec4<f32>, b: vec4<f32>, p: vec3<f32>) -> vec4<f32> {
    if (kind == PLANE) {
        let s = dot(a.xyz, p) + a.w;
        let n = a.xyz * (b.y / b.x);
        return vec4<f32>(n, select(0.0, abs(s) / b.x, s * b.y < 0.0));
    }
    if (kind == SPHERE) {
        let d = p - a.xyz;
        let l = length(d);
        let n = select(vec3<f32>(0.0, 0.0, 1.0), d / l, l > 0.0);
        return vec4<f32>(n, a.w - l);
    }
    var best = vec4<f32>(-1.0, 0.0, 0.0, p.x - a.x);
    let faces = array<vec4<f32>, 5>(
        vec4<f32>(1.0, 0.0, 0.0, b.x - p.x),
        vec4<f32>(0.0, -1.0, 0.0, p.y - a.y),
        vec4<f32>(0.0, 1.0, 0.0, b.y - p.y),
        vec4<f32>(0.0, 0.0, -1.0, p.z - a.z),
        vec4<f32>(0.0, 0.0, 1.0, b.z - p.z),
    );
    for (var f = 0u; f < 5u; f = f + 1u) {
        if (faces[f].w < best.w) {
            best = faces[f];
        }
    }
    return best;
}

// Obstacle o's contact with p (see shape_depth).
fn obstacle_depth(o: u32, p: vec3<f32>) -> vec4<f32> {
    let at = P.at.x + 3u * o;
    return shape_depth(scene[at].x, scene_f(at + 1u), scene_f(at + 2u), p);
}

// The part of a across the unit normal n.
fn across(a: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return a - n * dot(a, n);
}

// Coulomb friction without an anchor (the core's friction::sliding): against the tangential
// velocity, of size `normal`, capped as a damper of coefficient c_max.
fn sliding(n: vec3<f32>, v: vec3<f32>, normal: f32, c_max: f32) -> vec3<f32> {
    let vt = across(v, n);
    let speed = length(vt);
    if (speed > 0.0 && normal > 0.0) {
        return vt * -(min(normal, c_max * speed) / speed);
    }
    return vec3<f32>(0.0);
}

// An obstacle's (or a wall's) friction of coefficient `mu` on a point touching it at `depth`
// along n, tied to `anchor` (w = 0: not tied yet): the tangential spring and damper clamped to
// the Coulomb cone (the core's friction::obstacle).
fn obstacle_friction(p: vec3<f32>, v: vec3<f32>, depth: f32, n: vec3<f32>, anchor: vec4<f32>, c_max: f32, mu: f32) -> vec3<f32> {
    let kc = P.law.y;
    let limit = mu * kc * depth;
    if (anchor.w == 0.0) {
        return sliding(n, v, limit, c_max);
    }
    let f = across(p - anchor.xyz, n) * -kc - across(v, n) * P.law.z;
    let size = length(f);
    if (size > limit) {
        return f * (limit / size);
    }
    return f;
}

// The obstacles on point i at p moving at v, of mass m.
fn obstacles_on(i: u32, p: vec3<f32>, v: vec3<f32>, m: f32) -> vec3<f32> {
    var f = vec3<f32>(0.0);
    let kc = P.law.y;
    let dc = P.law.z;
    let c_max = m / P.law.x;
    let out = clearance(i);
    for (var o = 0u; o < P.counts.z; o = o + 1u) {
        var c = obstacle_depth(o, p);
        c.w = c.w - out;
        if (c.w > 0.0) {
            f = f + c.xyz * (kc * c.w - dc * dot(v, c.xyz));
            if (FRICTION) {
                let anchor = scene_f(anchor_at(o, i));
                f = f + obstacle_friction(p, v, c.w, c.xyz, anchor, c_max, P.law.w);
            }
        }
    }
    return f;
}

// Wall w's contact with a point at p (0 to 5: −x, +x, −y, +y, −z, +z; 6: the classic plane): the
// unit normal back into the box (or the plane's allowed side) and the depth (≤ 0: none), as the
// core's Aabb::wall_contact and Plane::contact give them.
fn wall_contact(w: u32, p: vec3<f32>) -> vec4<f32> {
    if (w == 6u) {
        return vec4<f32>(P.plane.xyz * (P.plane_side.y / P.plane_side.x), plane_depth(p));
    }
    let axis = w / 2u;
    var n = vec3<f32>(0.0);
    if (w % 2u == 0u) {
        n[axis] = 1.0;
        return vec4<f32>(n, P.box_lo[axis] - p[axis]);
    }
    n[axis] = -1.0;
    return vec4<f32>(n, p[axis] - P.box_hi[axis]);
}

// The walls' and the classic plane's friction on point i at p moving at v, of mass m (their
// penalty springs are in `finish`), in the core's order.
fn walls_friction_on(i: u32, p: vec3<f32>, v: vec3<f32>, m: f32) -> vec3<f32> {
    var f = vec3<f32>(0.0);
    let c_max = m / P.law.x;
    var walls = 6u;
    if (CLASSIC_PLANE) {
        walls = 7u;
    }
    let out = clearance(i);
    for (var w = 0u; w < walls; w = w + 1u) {
        var c = wall_contact(w, p);
        c.w = c.w - out;
        if (c.w > 0.0) {
            let anchor = scene_f(anchor_at(wall_slot(w), i));
            f = f + obstacle_friction(p, v, c.w, c.xyz, anchor, c_max, P.flags.y);
        }
    }
    return f;
}

// Everything but the springs on point i of body b, added to the springs' force f, over the mass,
// plus gravity, in the core's order.
fn finish(i: u32, p: vec3<f32>, v: vec3<f32>, f_springs: vec3<f32>, b: u32) -> vec3<f32> {
    var f = f_springs;
    if (FIELD) {
        f = f + field_force(p);
    }
    let kc = P.law.y;
    let dc = P.law.z;
    // A point resting outside its skin meets the walls and the plane that much further out.
    let out = clearance(i);
    let lo = P.box_lo.xyz - vec3<f32>(out);
    let hi = P.box_hi.xyz + vec3<f32>(out);
    f.x = f.x + wall(p.x, v.x, lo.x, hi.x, kc, dc);
    f.y = f.y + wall(p.y, v.y, lo.y, hi.y, kc, dc);
    f.z = f.z + wall(p.z, v.z, lo.z, hi.z, kc, dc);
    if (CLASSIC_PLANE) {
        let depth = plane_depth(p) - out;
        if (depth > 0.0) {
            let n = P.plane.xyz * (P.plane_side.y / P.plane_side.x);
            f = f + n * (kc * depth) - n * (dc * dot(v, n));
        }
    }
    let control = scene_f(P.at.z + 2u * i);
    f = f + control.xyz;
    let m = P.bodies[b].material.x;
    if (CONTACTS) {
        f = f + contacts_on(i);
    }
    if (OBSTACLES) {
        f = f + obstacles_on(i, p, v, m);
    }
    if (WALL_FRICTION) {
        f = f + walls_friction_on(i, p, v, m);
    }
    if (P.flags.w != 0.0) {
        let pulls = scene_f(P.at.z + 2u * i + 1u);
        f = f + pulls.xyz - p * pulls.w - v * control.w;
    }
    return f / m + P.gravity.xyz;
}

// Acceleration of point i at the stage in `state_in`; zero for a point that does not move
// (pinned, or outside its body).
fn acceleration(i: u32) -> vec3<f32> {
    let info = points[i];
    if ((info.y & MOVES) == 0u) {
        return vec3<f32>(0.0);
    }
    let p = position(i);
    let v = velocity(i);
    if (ONE_BODY) {
        return finish(i, p, v, springs_on(i, p, v, info.x, 0u), 0u);
    }
    let b = info.y & BODY_BITS;
    return finish(i, p, v, springs_on(i, p, v, info.x, b), b);
}
