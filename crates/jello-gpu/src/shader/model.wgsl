// Jello's explicit integrators on the GPU, in f32: one thread per lattice point gathers the forces
// on it (its up to 32 springs, the field, walls, plane, obstacles, contacts with other bodies,
// control forces and pulls, gravity) and applies one stage of its integrator. Each spring is
// evaluated at both its ends, and a point gathers the contact forces of the touches at its cells
// from per-sample records in a fixed order: no float atomics, so a run gives the same result
// every time.
//
// The module is this file (the model as the shader sees it: uniforms, buffers, helpers), then
// stage.wgsl (where the forces read the stage), forces.wgsl, contact.wgsl (contacts between
// bodies: what the forces read), touch.wgsl (the passes that find the touches before every force
// pass), check.wgsl (a step's end) and step.wgsl (the entry points), concatenated by the crate.
// A second module steps small lattices inside one workgroup: this file, forces.wgsl,
// contact.wgsl, check.wgsl and resident.wgsl.
//
// State buffers hold two vec4 per point: position (w unused), velocity (w unused).
// Every entry point reads the stage it evaluates from `state_in` and writes its own point only,
// so a dispatch never reads what it writes.

// One body: its stencil (per entry s, vec4 s / 4, component s % 4: the flat offset to the
// neighbour, rest length (m), stiffness (N/m), damping (N·s/m)) and what else its points share.
struct Body {
    offsets: array<vec4<i32>, 4>,
    rest: array<vec4<f32>, 4>,
    stiff: array<vec4<f32>, 4>,
    damp: array<vec4<f32>, 4>,
    // mass of a point (kg), 0, 0, 0
    material: vec4<f32>,
    // first point, where its per-spring values start in `scene` (NONE: it has none), 0, 0
    index: vec4<u32>,
}

const MAX_BODIES: u32 = 224u;

// What the model has, fixed when its pipelines are made, so that the code of what it does not
// have is compiled out: a single body; contacts between bodies; obstacles; friction (on
// obstacles and between bodies); friction on the walls and the classic plane; a sampled field;
// the classic plane (CLASSIC_PLANE); per-spring values; pins that move on paths; points resting
// outside their body's skin (CLEARANCE).
override ONE_BODY: bool = true;
override CONTACTS: bool = false;
override OBSTACLES: bool = false;
override FRICTION: bool = false;
override WALL_FRICTION: bool = false;
override FIELD: bool = false;
override CLASSIC_PLANE: bool = false;
override SPRING_VALUES: bool = false;
override PINS: bool = false;
override CLEARANCE: bool = false;
const NONE: u32 = 0xffffffffu;

struct Params {
    // points, bodies, obstacles, hash buckets of the cell grid (0: no contacts between bodies)
    counts: vec4<u32>,
    // dt (s), kCollision (N/m), dCollision (N·s/m), friction coefficient
    law: vec4<f32>,
    // escape margin (m), friction coefficient of the walls and the plane, 0, pulls present (1/0:
    // set_control changes it)
    flags: vec4<f32>,
    box_lo: vec4<f32>,
    box_hi: vec4<f32>,
    // a, b, c, d of the classic plane; then |(a, b, c)| and the allowed side (±1)
    plane: vec4<f32>,
    plane_side: vec4<f32>,
    gravity: vec4<f32>,
    field_lo: vec4<f32>,
    field_hi: vec4<f32>,
    // Where regions start in `scene` (in vec4): obstacles, field nodes, control, friction anchors
    // (NONE without friction on obstacles or walls)
    at: vec4<u32>,
    // field res, where the points' clearances start in `scene` (vec4; NONE without CLEARANCE),
    // 0, 0
    field_res: vec4<u32>,
    // Contacts between bodies (CONTACTS; see contact.wgsl and touch.wgsl): the side of a cell
    // grid's cell (m, the largest lattice spacing), its inverse, 0, 0
    grid_cell: vec4<f32>,
    // Pins on paths (PINS): where the points' paths start in `scene`, where the pin table does
    // (in vec4), a row of the table (vec4: two per path), 0
    pins: vec4<u32>,
    // samples, kept cells, room for the cell grid's entries, 0
    contact: vec4<u32>,
    // where in `scene` (vec4) the samples, the cells, the bodies' corner offsets and the
    // distances start
    contact_at: vec4<u32>,
    // where in `scene` (words) each point's list of sample corners starts and its entries, then
    // the same for its cell corners
    gather_at: vec4<u32>,
    // where in the contact buffer (words) the cell grid's entries, the cells' boxes, the
    // touches' counts and starts per cell; then their cursors, the touches by cell, the
    // samples' records, 0
    grid_at: vec4<u32>,
    grid_at2: vec4<u32>,
    bodies: array<Body, MAX_BODIES>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> state_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> base: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state_out: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> sums: array<vec4<f32>>;
// Per point: x has bit s set when the spring to the neighbour at +offset[s] exists, bit 16 + s
// when the one to the neighbour at −offset[s] does; y is its body, with MOVES and ACTIVE.
@group(0) @binding(5) var<storage, read> points: array<vec2<u32>>;
// Everything else the forces read, as vec4 of 32-bit words (floats by bitcast), by region (see
// Params.at and Body.index):
// - obstacles, three each: [kind, 0, 0, 0], then two vec4 of its shape (see `obstacle_depth`);
// - field nodes (res³ forces, N; i outermost, k innermost);
// - clearances (CLEARANCE), four to a vec4: how far each point rests outside its body's skin
//   (m), taken off its depth into the walls, the plane and the obstacles (the core's
//   model::clearance);
// - control, two per point: [control force plus a uniform field's (N), Σ pull damping (N·s/m)],
//   [Σ pull stiffness × target (N), Σ pull stiffness (N/m)];
// - per-spring values of bodies that have them: for the point p of a body and stencil entry s,
//   at 16 (p − first) + s, the rest length, stiffness and damping of the spring to +offset[s];
// - friction anchors: where the point is tied, and 1 (or 0: not tied); per obstacle and point
//   (FRICTION), then per wall (−x, +x, −y, +y, −z, +z, then the classic plane) and point
//   (WALL_FRICTION): see `anchor_at`;
// - pins on paths (PINS), one per point: [where its path has it at offset zero (m), the index
//   of its path] (w NONE: on no path);
// - the pin table (PINS), rewritten before every batch of steps: a row per step of the batch,
//   in it per path [its offset at the step's end (m), 0], [its velocity there (m/s), 0];
// - contacts between bodies (CONTACTS; see contact.wgsl): per body its cells' corner offsets;
//   the signed distances; the cells; the samples; per point its sample and cell corners.
@group(0) @binding(6) var<storage, read> scene: array<vec4<u32>>;
// The contact buffer (see touch.wgsl), read by the force passes.
@group(0) @binding(7) var<storage, read> grid: array<u32>;
// [0]: 1 once a step ended unsound; [1]: the lowest point found at fault; [2]: the deepest
// penetration into a wall, the plane or an obstacle at a step's end (m, the bits of a
// non-negative f32); [3]: where the current step's row starts in the pin table (vec4 from the
// table's start; 0 at a batch's start, advanced by pins_next after every step); [4]: the steps
// left in a submission of resident.wgsl; [5]: 1 once the cell grid had no room for an entry
// (see touch.wgsl).
@group(0) @binding(8) var<storage, read_write> status: array<atomic<u32>>;
// The contact buffer as the contact passes build it, and the scene as the anchor pass updates
// it.
@group(0) @binding(9) var<storage, read_write> grid_rw: array<atomic<u32>>;
@group(0) @binding(10) var<storage, read_write> scene_rw: array<vec4<u32>>;

// Point flags in points[i].y, above the body index.
const MOVES: u32 = 0x80000000u;
const ACTIVE: u32 = 0x40000000u;
const BODY_BITS: u32 = 0x3fffffffu;

const WORKGROUP: u32 = 64u;

fn point_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * WORKGROUP;
}

fn scene_f(at: u32) -> vec4<f32> {
    return bitcast<vec4<f32>>(scene[at]);
}

// How far point i rests outside its body's skin (m; 0 without CLEARANCE).
fn clearance(i: u32) -> f32 {
    if (!CLEARANCE) {
        return 0.0;
    }
    return scene_f(P.field_res.y + i / 4u)[i % 4u];
}

// Where point i's friction anchor on anchored surface `slot` is in `scene`: the obstacles' slots
// first (with FRICTION), then the walls' (see `wall_slot`).
fn anchor_at(slot: u32, i: u32) -> u32 {
    return P.at.w + slot * P.counts.x + i;
}

// The anchor slot of wall w (0 to 5: −x, +x, −y, +y, −z, +z; 6: the classic plane).
fn wall_slot(w: u32) -> u32 {
    return select(0u, P.counts.z, FRICTION) + w;
}
