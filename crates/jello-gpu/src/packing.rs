//! A model as the shader reads it (see `shader/model.wgsl`): the uniform block with every body's
//! stencil, the per-point links and flags, and the scene buffer of obstacles, field nodes,
//! control forces, per-spring values, friction anchors, the pins on paths with the table of
//! their steps, and the bodies' contact surfaces; and the contact buffer's layout. Here is the
//! only place that knows those layouts on the host.

use jello_core::model::contact_surface::CORNERS;
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
    contact: [u32; 4],
    contact_at: [u32; 4],
    gather_at: [u32; 4],
    grid_at: [u32; 4],
    grid_at2: [u32; 4],
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
/// [`MAX_BODIES`] bodies, an implicit integrator, or self-contact.
pub fn unsupported(model: &Model, _control: &Control) -> Option<String> {
    let bodies = model.bodies().len();
    if bodies > MAX_BODIES {
        Some(format!("{bodies} bodies (it steps at most {MAX_BODIES})"))
    } else if model.self_contact {
        Some("self-contact (the GPU's contacts are between different bodies)".to_string())
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
    /// The contact buffer's layout (`None`: no contacts between bodies, as in a model of one
    /// body).
    pub contacts: Option<ContactLayout>,
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

        // How far each point rests outside its body's skin (the core's `Model::clearance`), four
        // to a vec4, when any does.
        let clearance = model.clearance();
        header.field_res[1] = if clearance.is_empty() {
            NONE
        } else {
            let at = scene.len();
            scene.extend(clearance.chunks(4).map(|c| {
                let mut four = [0.0f32; 4];
                for (f, &c) in four.iter_mut().zip(c) {
                    *f = c as f32;
                }
                bits(four)
            }));
            at as u32
        };

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
            record.material = [body.material.mass as f32, 0.0, 0.0, 0.0];
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

        // Contacts between bodies: their surfaces into the scene, the grid's layout.
        let contacts = pack_contacts(model, &mut scene, &mut header);

        header.counts = [
            n as u32,
            bodies.len() as u32,
            model.obstacles.len() as u32,
            contacts.map_or(0, |c| c.buckets as u32),
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
            ("CONTACTS", flag(contacts.is_some())),
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
            ("CLEARANCE", flag(!clearance.is_empty())),
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
            contacts,
            uniform_field,
            overrides,
        }
    }
}

/// Grid cells a body's cell may overlap on average (its box, as deformed now), at most: up to
/// three along each axis, as a cell turned or stretched to up to twice the grid's side does.
/// More overflows the contact buffer, which the step reports (see `status` in `model.wgsl`).
pub const ENTRIES_PER_CELL: usize = 27;

/// The contact buffer's layout (see `touch.wgsl`): its parts' sizes and where each starts (in
/// 32-bit words).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ContactLayout {
    /// Samples (of every body), kept cells (of every body), hash buckets of the cell grid (a
    /// power of two: as many as the core's), and room for the grid's entries.
    pub samples: usize,
    pub cells: usize,
    pub buckets: usize,
    pub entries: usize,
}

impl ContactLayout {
    fn new(samples: usize, cells: usize) -> Self {
        ContactLayout {
            samples,
            cells,
            buckets: (2 * cells).next_power_of_two(),
            entries: ENTRIES_PER_CELL * cells,
        }
    }

    /// Where the parts after the buckets' counts, starts and cursors begin: the grid's entries,
    /// the cells' boxes, the touches' counts, starts and cursors per cell, the touches sorted by
    /// cell, the samples' records; then the end (the buffer's length).
    pub fn offsets(&self) -> [usize; 8] {
        let (b, c, s) = (self.buckets, self.cells, self.samples);
        let entries = 3 * b + 1;
        let boxes = entries + self.entries;
        let counts = boxes + 6 * c;
        let starts = counts + c;
        let cursors = starts + c + 1;
        let touches = cursors + c;
        let records = touches + s;
        [
            entries,
            boxes,
            counts,
            starts,
            cursors,
            touches,
            records,
            records + 8 * s,
        ]
    }

    /// Bytes of the contact buffer.
    pub fn bytes(&self) -> usize {
        4 * self.offsets()[7]
    }
}

/// Where a cell record's third word keeps its body's distance-grid refinement (see
/// `contact.wgsl`): the bits from here up; the grid's points along y below.
const REFINE_SHIFT: usize = 24;

/// The contact surfaces of `model`'s bodies (when it has two or more, and a cell to be inside)
/// into the scene (see `contact.wgsl`), and where they are into the header; the contact
/// buffer's layout.
fn pack_contacts(
    model: &Model,
    scene: &mut Vec<[u32; 4]>,
    header: &mut Header,
) -> Option<ContactLayout> {
    let bodies = model.bodies();
    let samples: usize = bodies
        .iter()
        .map(|b| b.contact_surface().sample_count())
        .sum();
    let cells: usize = bodies
        .iter()
        .map(|b| b.contact_surface().cells().len())
        .sum();
    if bodies.len() < 2 || samples == 0 || cells == 0 {
        return None;
    }
    let layout = ContactLayout::new(samples, cells);
    let n = model.point_count();
    // Per body, its cells' corners as flat offsets from the lower corner.
    let offsets_at = scene.len();
    for body in bodies {
        let o = body.contact_surface().corner_offsets().map(|o| o as u32);
        scene.extend([[o[0], o[1], o[2], o[3]], [o[4], o[5], o[6], o[7]]]);
    }
    // The signed distances, body after body, as f32 words; where each body's start.
    let mut words: Vec<u32> = Vec::new();
    let distances_at = scene.len();
    let starts: Vec<usize> = bodies
        .iter()
        .map(|body| {
            let start = 4 * distances_at + words.len();
            let (distance, _) = body.contact_surface().distance_grid();
            words.extend(distance.iter().map(|&d| (d as f32).to_bits()));
            start
        })
        .collect();
    push_words(scene, &words);
    // The cells: [lower corner (model index), where its block of distances starts (word), the
    // distance grid's points along y with its refinement in the top byte (REFINE_SHIFT), its
    // points along z].
    let cells_at = scene.len();
    let mut point_cells: Vec<(u32, u32)> = Vec::new();
    for (body, start) in bodies.iter().zip(&starts) {
        let surface = body.contact_surface();
        let [_, ny, nz] = body.lattice().counts;
        let (_, [_, ry, rz]) = surface.distance_grid();
        let refine = surface.refine();
        assert!(
            refine < 1 << (32 - REFINE_SHIFT) && ry < 1 << REFINE_SHIFT,
            "a distance grid too fine to pack ({refine} per cell, {ry} points along y)"
        );
        let first = body.points().start;
        let offsets = surface.corner_offsets();
        for &c in surface.cells() {
            let c = c as usize;
            let (ci, cj, ck) = (c / (ny * nz), c / nz % ny, c % nz);
            let base = start + ((refine * ci * ry) + refine * cj) * rz + refine * ck;
            let g = (scene.len() - cells_at) as u32;
            for (k, o) in offsets.iter().enumerate() {
                point_cells.push(((first + c + o) as u32, 8 * g + k as u32));
            }
            let ry_refine = (ry | refine << REFINE_SHIFT) as u32;
            scene.push([(first + c) as u32, base as u32, ry_refine, rz as u32]);
        }
    }
    // The samples: [lower corner of its cell (model index), its place (u, v, w)].
    let samples_at = scene.len();
    let mut point_samples: Vec<(u32, u32)> = Vec::new();
    for body in bodies {
        let surface = body.contact_surface();
        let first = body.points().start;
        let offsets = surface.corner_offsets();
        for sample in surface.samples() {
            let s = (scene.len() - samples_at) as u32;
            let corner = first + sample.corner() as usize;
            let local = sample.local().map(|u| u as f32);
            // The corners the sample's force goes to: those of nonzero weight (as the shader
            // computes it).
            for (k, (o, [a, b, c])) in offsets.iter().zip(CORNERS).enumerate() {
                let f = |s: usize, t: f32| if s == 1 { t } else { 1.0 - t };
                if f(a, local[0]) * f(b, local[1]) * f(c, local[2]) != 0.0 {
                    point_samples.push(((corner + o) as u32, 8 * s + k as u32));
                }
            }
            let [u, v, w] = local.map(f32::to_bits);
            scene.push([corner as u32, u, v, w]);
        }
    }
    // Per point, its samples' corners and its cells' corners (each `8 · index + corner`) in
    // the order they were listed: by sample (cell), then corner.
    let mut csr = Vec::new();
    let mut gather_at = [0u32; 4];
    for (list, at) in [(point_samples, 0), (point_cells, 2)] {
        let mut starts = vec![0u32; n + 1];
        for &(p, _) in &list {
            starts[p as usize + 1] += 1;
        }
        for p in 0..n {
            starts[p + 1] += starts[p];
        }
        let mut entries = vec![0u32; list.len()];
        let mut next = starts.clone();
        for &(p, e) in &list {
            entries[next[p as usize] as usize] = e;
            next[p as usize] += 1;
        }
        let base = 4 * scene.len() + csr.len();
        gather_at[at] = base as u32;
        gather_at[at + 1] = (base + starts.len()) as u32;
        csr.extend(starts);
        csr.extend(entries);
    }
    push_words(scene, &csr);

    let h = bodies
        .iter()
        .map(|b| {
            let s = b.lattice().spacing();
            s.x.max(s.y).max(s.z)
        })
        .fold(0.0, f64::max);
    let side = if h > 0.0 { h } else { 1.0 };
    header.grid_cell = [side as f32, (1.0 / side) as f32, 0.0, 0.0];
    header.contact = [samples as u32, cells as u32, layout.entries as u32, 0];
    header.contact_at = [
        samples_at as u32,
        cells_at as u32,
        offsets_at as u32,
        distances_at as u32,
    ];
    header.gather_at = gather_at;
    let o = layout.offsets().map(|o| o as u32);
    header.grid_at = [o[0], o[1], o[2], o[3]];
    header.grid_at2 = [o[4], o[5], o[6], 0];
    Some(layout)
}

/// 32-bit words into the scene, four to a vec4 (the last padded with zeros).
fn push_words(scene: &mut Vec<[u32; 4]>, words: &[u32]) {
    scene.extend(words.chunks(4).map(|c| {
        let mut v = [0; 4];
        v[..c.len()].copy_from_slice(c);
        v
    }));
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
