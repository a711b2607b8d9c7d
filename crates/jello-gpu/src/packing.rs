//! A model as the shader reads it (see `shader/model.wgsl`): the uniform block with every body's
//! stencil, the per-point links and flags, and the scene buffer of obstacles, field nodes,
//! control forces, per-spring values, friction anchors, and the pins on paths with the table of
//! their steps. Here is the only place that knows those layouts on the host.

use jello_core::model::lattice::STENCIL;
use jello_core::{Control, Model, Obstacle, State, Vec3};

/// Bodies the uniform block holds, at most (the shader's `MAX_BODIES`: WebGPU's 64 KiB of
/// uniforms).
pub const MAX_BODIES: usize = 224;

/// A word of `scene` or of the per-spring values that marks "none" (the shader's `NONE`).
const NONE: u32 = u32::MAX;

/// Point flags above the body index (the shader's `MOVES` and `ACTIVE`).
const MOVES: u32 = 1 << 31;
const ACTIVE: u32 = 1 << 30;

/// Bytes the pin table may take, at most (1 MiB: a batch of 512 steps for up to 64 paths); a
/// model with more paths steps in shorter batches (of one step at least).
const PIN_TABLE_MAX_BYTES: usize = 1 << 20;

/// Obstacle kinds (the shader's `PLANE`, `SPHERE` and `SOLID_BOX`).
const PLANE: u32 = 0;
const SPHERE: u32 = 1;
const SOLID_BOX: u32 = 2;

/// The uniform block before the bodies (`Params` in `model.wgsl`): every field 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Header {
    counts: [u32; 4],
    law: [f32; 4],
    flags: [f32; 4],
    box_lo: [f32; 4],
    box_hi: [f32; 4],
    plane: [f32; 4],
    plane_side: [f32; 4],
    gravity: [f32; 4],
    field_lo: [f32; 4],
    field_hi: [f32; 4],
    at: [u32; 4],
    field_res: [u32; 4],
    grid_cell: [f32; 4],
    pins: [u32; 4],
}

/// One body in the uniform block (`Body` in `model.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct BodyRecord {
    offsets: [[i32; 4]; 4],
    rest: [[f32; 4]; 4],
    stiff: [[f32; 4]; 4],
    damp: [[f32; 4]; 4],
    material: [f32; 4],
    index: [u32; 4],
}

/// Bytes of the uniform block: the header and `MAX_BODIES` bodies.
pub const UNIFORM_BYTES: usize = size_of::<Header>() + MAX_BODIES * size_of::<BodyRecord>();

fn vec4(v: Vec3) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, 0.0]
}

/// The state as the shader holds it: per point its position, then its velocity, as vec4.
pub fn pack_state(state: &State) -> Vec<[f32; 4]> {
    state
        .pos
        .iter()
        .zip(&state.vel)
        .flat_map(|(&p, &v)| [vec4(p), vec4(v)])
        .collect()
}

/// The state [`pack_state`] packed, back in f64 (time and step count zero).
pub fn unpack_state(data: &[[f32; 4]]) -> State {
    let v3 = |c: &[f32; 4]| Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
    let pos = data.iter().step_by(2).map(v3).collect();
    let vel = data.iter().skip(1).step_by(2).map(v3).collect();
    State::new(pos, vel)
}

fn bits(v: [f32; 4]) -> [u32; 4] {
    v.map(f32::to_bits)
}

/// What in `model` (with `control`) the shader does not cover, if anything: more than
/// [`MAX_BODIES`] bodies, or an implicit integrator.
pub fn unsupported(model: &Model, _control: &Control) -> Option<String> {
    let bodies = model.bodies().len();
    if bodies > MAX_BODIES {
        Some(format!("{bodies} bodies (it steps at most {MAX_BODIES})"))
    } else if model.integrator.is_implicit() {
        Some(format!(
            "the implicit integrator {} (the GPU steps Euler, SymplecticEuler, RK2 and RK4)",
            model.integrator
        ))
    } else {
        None
    }
}

/// What the shader reads of a model, ready to upload.
pub struct Packed {
    /// The uniform block, [`UNIFORM_BYTES`] long.
    pub uniform: Vec<u8>,
    /// Per point: its link bits, and its body with its flags.
    pub points: Vec<[u32; 2]>,
    /// The scene buffer.
    pub scene: Vec<[u32; 4]>,
    /// Where the control forces start in `scene` (vec4), where the friction anchors do (`None`
    /// without friction on obstacles or walls), and how many per point there are.
    pub control_at: usize,
    pub anchors_at: Option<usize>,
    pub anchor_slots: usize,
    /// Where the points' paths start in `scene` (vec4; see [`pin_points`]), where the pin table
    /// does, and the steps it has rows for, which a batch may not exceed (`None` without pins on
    /// paths).
    pub pins: Option<(usize, usize, usize)>,
    /// Hash buckets of the contact grid (0: a model of one body).
    pub buckets: usize,
    /// A uniform field's force (N), added to every point's control force.
    pub uniform_field: Vec3,
    /// The shader's overrides (`ONE_BODY`, `CONTACTS`, ...): what the model has.
    pub overrides: Vec<(&'static str, f64)>,
}

impl Packed {
    /// Packs `model` with `control`'s forces and pulls (which must be covered: see
    /// [`unsupported`]) and its pins on paths as they are in `state` (which has a point for each
    /// of the model's), with room in the pin table for batches of up to `batch` steps.
    pub fn new(model: &Model, control: &Control, state: &State, batch: usize) -> Packed {
        let bodies = model.bodies();
        let n = model.point_count();
        let mut header = Header {
            law: [
                model.dt as f32,
                model.k_collision as f32,
                model.d_collision as f32,
                model.friction as f32,
            ],
            box_lo: vec4(model.bounds.min),
            box_hi: vec4(model.bounds.max),
            gravity: vec4(model.gravity),
            ..Header::default()
        };
        if let Some(plane) = model.plane {
            let [a, b, c, d] = plane.coeffs;
            header.plane = [a as f32, b as f32, c as f32, d as f32];
            header.plane_side = [plane.normal_length() as f32, plane.side as f32, 0.0, 0.0];
        }

        // Obstacles first in the scene.
        let mut scene: Vec<[u32; 4]> = Vec::new();
        for obstacle in &model.obstacles {
            let (kind, a, b) = match *obstacle {
                Obstacle::Plane(plane) => {
                    let [a, b, c, d] = plane.coeffs;
                    (
                        PLANE,
                        [a as f32, b as f32, c as f32, d as f32],
                        [plane.normal_length() as f32, plane.side as f32, 0.0, 0.0],
                    )
                }
                Obstacle::Sphere(s) => {
                    let c = s.centre;
                    (
                        SPHERE,
                        [c.x as f32, c.y as f32, c.z as f32, s.radius as f32],
                        [0.0; 4],
                    )
                }
                Obstacle::Box(b) => (SOLID_BOX, vec4(b.min), vec4(b.max)),
            };
            scene.extend([[kind, 0, 0, 0], bits(a), bits(b)]);
        }

        // The field: a uniform one is a constant force, added to the control forces.
        let field_at = scene.len();
        let mut uniform_field = Vec3::ZERO;
        let mut sampled = false;
        if let Some(field) = &model.field {
            match field.uniform() {
                Some(f) => uniform_field = f,
                None => {
                    sampled = true;
                    scene.extend(field.forces().iter().map(|&f| bits(vec4(f))));
                    let b = field.bounds();
                    header.field_lo = vec4(b.min);
                    header.field_hi = vec4(b.max);
                    header.field_res = [field.res() as u32, 0, 0, 0];
                }
            }
        }

        let control_at = scene.len();
        scene.extend(control_words(model, control, uniform_field));

        // The bodies: their stencils into the uniform block, their springs into the link bits
        // (and, for a body with its own values, into the scene).
        let mut records = vec![BodyRecord::default(); MAX_BODIES];
        let mut points = vec![[0u32; 2]; n];
        for (b, (body, record)) in bodies.iter().zip(&mut records).enumerate() {
            let [_, ny, nz] = body.lattice().counts;
            let spacing = body.lattice().spacing();
            for (s, (d, kind)) in STENCIL.iter().enumerate() {
                let (e, c) = (s / 4, s % 4);
                record.offsets[e][c] = ((d[0] * ny as isize + d[1]) * nz as isize + d[2]) as i32;
                record.rest[e][c] = Vec3::new(
                    d[0] as f64 * spacing.x,
                    d[1] as f64 * spacing.y,
                    d[2] as f64 * spacing.z,
                )
                .length() as f32;
                record.stiff[e][c] = body.material.stiffness[*kind as usize] as f32;
                record.damp[e][c] = body.material.damping[*kind as usize] as f32;
            }
            let first = body.points().start;
            record.material = [
                body.material.mass as f32,
                body.contact_radius() as f32,
                0.0,
                0.0,
            ];
            let table = body.spring_table().is_some().then_some(scene.len());
            record.index = [first as u32, table.map_or(NONE, |t| t as u32), 0, 0];
            if table.is_some() {
                scene.resize(scene.len() + 16 * body.len(), [0; 4]);
            }
            body.for_each_spring_entry(|spring, s| {
                points[first + spring.a][0] |= 1 << s;
                points[first + spring.b][0] |= 1 << (16 + s);
                if let Some(t) = table {
                    scene[t + 16 * spring.a + s] = bits([
                        spring.rest as f32,
                        spring.stiffness as f32,
                        spring.damping as f32,
                        0.0,
                    ]);
                }
            });
            for q in 0..body.len() {
                let flags = if body.is_active(q) { MOVES | ACTIVE } else { 0 };
                points[first + q][1] = b as u32 | flags;
            }
        }
        for &p in &model.pins {
            points[p as usize][1] &= !MOVES;
        }

        // Friction anchors, none tied yet: per obstacle and point (with friction), then per
        // wall (six, then the plane's slot) and point (with wall friction).
        let obstacle_slots = if model.friction != 0.0 {
            model.obstacles.len()
        } else {
            0
        };
        let wall_slots = if model.wall_friction != 0.0 { 7 } else { 0 };
        let anchor_slots = obstacle_slots + wall_slots;
        let anchors_at = (anchor_slots > 0).then(|| {
            let at = scene.len();
            scene.resize(at + anchor_slots * n, [0; 4]);
            at
        });

        // Pins on paths: each point's, then the table, filled before every batch (see
        // `pin_steps`).
        let on_paths = model.pin_motions.iter().any(|m| !m.points.is_empty());
        let pins = on_paths.then(|| {
            let points_at = scene.len();
            scene.extend(pin_points(model, state));
            let row = 2 * model.pin_motions.len();
            let rows = (PIN_TABLE_MAX_BYTES / (16 * row)).clamp(1, batch.max(1));
            let table_at = scene.len();
            scene.resize(table_at + rows * row, [0; 4]);
            header.pins = [points_at as u32, table_at as u32, row as u32, 0];
            (points_at, table_at, rows)
        });

        // Contacts between bodies: as many buckets as the core's grid.
        let buckets = if bodies.len() < 2 {
            0
        } else {
            let active: usize = bodies.iter().map(|b| b.active_count()).sum();
            let cell = 2.0
                * bodies
                    .iter()
                    .map(|b| b.contact_radius())
                    .fold(0.0, f64::max);
            header.grid_cell = [cell as f32, (1.0 / cell) as f32, 0.0, 0.0];
            (2 * active).next_power_of_two()
        };

        header.counts = [
            n as u32,
            bodies.len() as u32,
            model.obstacles.len() as u32,
            buckets as u32,
        ];
        header.flags = [
            model.escape_margin as f32,
            model.wall_friction as f32,
            0.0,
            pulls_flag(control),
        ];
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let overrides = vec![
            ("ONE_BODY", flag(bodies.len() == 1)),
            ("CONTACTS", flag(buckets > 0)),
            ("OBSTACLES", flag(!model.obstacles.is_empty())),
            ("FRICTION", flag(model.friction > 0.0)),
            ("WALL_FRICTION", flag(model.wall_friction > 0.0)),
            ("FIELD", flag(sampled)),
            ("CLASSIC_PLANE", flag(model.plane.is_some())),
            (
                "SPRING_VALUES",
                flag(bodies.iter().any(|b| b.spring_table().is_some())),
            ),
            ("PINS", flag(on_paths)),
        ];
        header.at = [
            0,
            field_at as u32,
            control_at as u32,
            anchors_at.map_or(NONE, |a| a as u32),
        ];
        let mut uniform = bytemuck::bytes_of(&header).to_vec();
        uniform.extend_from_slice(bytemuck::cast_slice(&records));
        debug_assert_eq!(uniform.len(), UNIFORM_BYTES);
        Packed {
            uniform,
            points,
            scene,
            control_at,
            anchors_at,
            anchor_slots,
            pins,
            buckets,
            uniform_field,
            overrides,
        }
    }
}

/// The control region of the scene: per point, [its control force plus the uniform field's,
/// Σ pull damping], [Σ pull stiffness × target, Σ pull stiffness].
pub fn control_words(model: &Model, control: &Control, uniform_field: Vec3) -> Vec<[u32; 4]> {
    let n = model.point_count();
    let mut words = vec![[0.0f64; 4]; 2 * n];
    for p in 0..n {
        let f = control.forces.get(p).copied().unwrap_or(Vec3::ZERO) + uniform_field;
        words[2 * p] = [f.x, f.y, f.z, 0.0];
    }
    for pull in &control.pulls {
        let p = pull.point as usize;
        if p >= n {
            continue;
        }
        let k = pull.target * pull.stiffness;
        words[2 * p][3] += pull.damping;
        let sums = &mut words[2 * p + 1];
        *sums = [
            sums[0] + k.x,
            sums[1] + k.y,
            sums[2] + k.z,
            sums[3] + pull.stiffness,
        ];
    }
    words.iter().map(|w| bits(w.map(|c| c as f32))).collect()
}

/// The points' paths as `model.wgsl` reads them, for `state` (which has a point for each of the
/// model's): per point on a path (the last that names it, as the core applies them in order),
/// where the path has it at offset zero (its position less the path's offset at the state's
/// time, in f64, then in f32) and the path's index; `NONE` for the others.
pub fn pin_points(model: &Model, state: &State) -> Vec<[u32; 4]> {
    let mut words = vec![[0, 0, 0, NONE]; model.point_count()];
    for (index, m) in model.pin_motions.iter().enumerate() {
        let offset = m.motion.offset(state.time);
        for &p in &m.points {
            let p = p as usize;
            if let (Some(word), Some(&pos)) = (words.get_mut(p), state.pos.get(p)) {
                let [x, y, z, _] = bits(vec4(pos - offset));
                *word = [x, y, z, index as u32];
            }
        }
    }
    words
}

/// The pin table's rows for `steps` steps from `time` (see `model.wgsl`): per step and path, the
/// path's offset and velocity at the step's end, in f64 as the core computes them (the time
/// summed step by step, as the core sums it), then in f32.
pub fn pin_steps(model: &Model, time: f64, steps: usize) -> Vec<[u32; 4]> {
    let mut words = Vec::with_capacity(steps * 2 * model.pin_motions.len());
    let mut t = time;
    for _ in 0..steps {
        t += model.dt;
        for m in &model.pin_motions {
            words.extend([
                bits(vec4(m.motion.offset(t))),
                bits(vec4(m.motion.velocity(t))),
            ]);
        }
    }
    words
}

/// Whether `control` has pulls: the uniform block's flag, which [`Packed::new`] set from the
/// control it was given.
pub fn pulls_flag(control: &Control) -> f32 {
    if control.pulls.is_empty() {
        0.0
    } else {
        1.0
    }
}

/// Points a model may have to step inside one workgroup (`shader/resident.wgsl`: two per thread
/// of its 256, whose stage takes 12 KiB of WebGPU's 16 KiB of workgroup memory).
pub const RESIDENT_POINTS: usize = 512;

/// Whether `model` can step inside one workgroup (`resident.wgsl`): one body of at most
/// [`RESIDENT_POINTS`] points, no friction anchors to update between steps (friction with
/// obstacles or walls), no pins moving on paths, an explicit integrator.
pub fn fits_resident(model: &Model) -> bool {
    model.bodies().len() == 1
        && model.point_count() <= RESIDENT_POINTS
        && (model.friction == 0.0 || model.obstacles.is_empty())
        && model.wall_friction == 0.0
        && model.pin_motions.is_empty()
        && !model.integrator.is_implicit()
}

/// Byte offset of the pulls flag in the uniform block (`flags.w`).
pub const PULLS_FLAG_OFFSET: u64 = (std::mem::offset_of!(Header, flags) + 12) as u64;
