//! [`Body`]: one soft body of a model. A lattice of mass points (every point of a box, or only
//! the corners of the cells a shape keeps), the springs between them, its material, where it
//! rests, and the skin it carries.
//!
//! ## Which springs a body with holes has
//!
//! A body made of kept cells (a voxelised mesh) has the springs of the lattice stencil that
//! belong to kept cells:
//! - a **structural** spring (a cell edge) when any of the (up to four) cells around that edge is
//!   kept;
//! - a **face diagonal** when either of the (up to two) cells on that face is kept;
//! - a **body diagonal** when its cell is kept;
//! - a **bend** spring when both structural springs it spans exist.
//!
//! Its points are the corners of kept cells; every spring joins two of them. When every cell is
//! kept that is exactly the full stencil, so a box is the special case with no holes (and is
//! stepped by the same kernel without link bits). Two kept cells that touch only along an edge
//! are joined by that edge's structural spring alone, so a shape does not grow springs across a
//! gap in it.

use std::ops::Range;

use crate::model::error::ModelError;
use std::sync::{Arc, OnceLock};

use crate::model::contact_surface::ContactSurface;
use crate::model::lattice::{Lattice, SpringKind, STENCIL};
use crate::model::skin::{enclosed_volume, Skin};
use crate::model::springs::{Spring, SpringScale, SpringTable, Springs};
use crate::model::voxel::Voxels;
use crate::vec3::Vec3;

/// What a body is made of: the mass of each point, and the stiffness and damping of each spring
/// kind. Per-spring values are exact; [`Material::from_modulus`] derives them from
/// resolution-independent ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Mass of every point (kg).
    pub mass: f64,
    /// Stiffness per spring kind (N/m), indexed by `SpringKind as usize`.
    pub stiffness: [f64; 3],
    /// Damping per spring kind (N·s/m), indexed by `SpringKind as usize`.
    pub damping: [f64; 3],
}

impl Material {
    /// The classic jello: every spring 200 N/m and 0.25 N·s/m, 1/512 kg per point.
    pub fn classic() -> Self {
        use crate::model::defaults;
        Material {
            mass: defaults::MASS,
            stiffness: [defaults::K_ELASTIC; 3],
            damping: [defaults::D_ELASTIC; 3],
        }
    }

    /// A material given independently of the lattice's resolution, for a lattice of spacing `h`
    /// (m) with `points` points filling `volume` (m³): every spring gets stiffness `modulus · h`
    /// and damping `viscosity · h`, and every point the mass `density · volume / points`.
    ///
    /// Why this is resolution-independent: a lattice of springs `k` at spacing `h` has a stress
    /// per strain proportional to `k / h`, and its points a mass per volume of `m / h³`, so the
    /// speed of its elastic waves, `h·√(k/m)`, becomes `√(modulus/density)` whatever `h`, and the
    /// decay rate of a mode of wavelength `λ` (`d/m · (h/λ)²`) becomes `viscosity/(density λ²)`:
    /// refining the lattice keeps the body's frequencies, damping and total mass. `modulus` is
    /// Young's-modulus-like (Pa) but not equal to the lattice's Young's modulus, which also
    /// depends on the shear and bend springs.
    pub fn from_modulus(
        modulus: f64,
        viscosity: f64,
        density: f64,
        h: f64,
        volume: f64,
        points: usize,
    ) -> Self {
        Material {
            mass: density * volume / points as f64,
            stiffness: [modulus * h; 3],
            damping: [viscosity * h; 3],
        }
    }

    /// Fails on a value that is not finite, a mass or stiffness that is not positive, or a
    /// negative damping.
    pub fn check(&self) -> Result<(), ModelError> {
        crate::model::error::positive("mass", self.mass)?;
        for kind in SpringKind::ALL {
            crate::model::error::positive(
                &format!("{} stiffness", kind.name()),
                self.stiffness[kind as usize],
            )?;
            crate::model::error::non_negative(
                &format!("{} damping", kind.name()),
                self.damping[kind as usize],
            )?;
        }
        Ok(())
    }
}

/// One soft body: a lattice with the cells it keeps, its material, its rest placement and skin.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    lattice: Lattice,
    /// Per cell (`(nx−1)(ny−1)(nz−1)`, flat index `(i·cy + j)·cz + k`), whether it is kept;
    /// `None` for a full box.
    cells: Option<Vec<bool>>,
    /// Per point, bit `s` set when the spring of stencil entry `s` from this point exists; empty
    /// for a full box.
    links: Vec<u16>,
    /// Per point, whether it is a corner of a kept cell; empty for a full box.
    active: Vec<bool>,
    /// Points that take part (all of a box, the corners of kept cells otherwise).
    active_count: usize,
    /// Per-spring factors on the rest lengths, stiffnesses and dampings, when any differs from
    /// 1 (see [`crate::model::springs`]).
    table: Option<SpringTable>,
    /// What it is made of.
    pub material: Material,
    /// Where lattice point `(0, 0, 0)` rests (m).
    pub origin: Vec3,
    /// Rotation of the rest shape about `origin` (rows of a rotation matrix).
    pub rotation: [Vec3; 3],
    /// The surface mesh that follows the lattice, when the body was made from one.
    pub skin: Option<Skin>,
    /// Flat index of the body's first point in the model's point arrays (set by the model).
    pub(crate) first: usize,
    /// The surface other bodies touch, computed when first asked for (see
    /// [`Body::contact_surface`]).
    contact: Derived<ContactSurface>,
    /// How far each lattice point rests outside the skin, computed when first asked for (see
    /// [`Body::clearance`]).
    clearance: Derived<Vec<f64>>,
}

/// Something computed from a body once, when first asked for (its [`ContactSurface`], its
/// points' clearance): derived from the body, so it plays no part in comparing bodies, and
/// shared by its clones.
#[derive(Clone)]
struct Derived<T>(OnceLock<Arc<T>>);

impl<T> Default for Derived<T> {
    fn default() -> Self {
        Derived(OnceLock::new())
    }
}

impl<T> PartialEq for Derived<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<T> std::fmt::Debug for Derived<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.get().is_some() {
            "Derived(computed)"
        } else {
            "Derived(not yet)"
        })
    }
}

/// The identity rotation.
pub const IDENTITY: [Vec3; 3] = [
    Vec3::new(1.0, 0.0, 0.0),
    Vec3::new(0.0, 1.0, 0.0),
    Vec3::new(0.0, 0.0, 1.0),
];

/// Rows of the rotation by `rx` degrees about x, then `ry` about y, then `rz` about z
/// (`R = Rz · Ry · Rx`).
pub fn rotation_xyz([rx, ry, rz]: [f64; 3]) -> [Vec3; 3] {
    let (sx, cx) = rx.to_radians().sin_cos();
    let (sy, cy) = ry.to_radians().sin_cos();
    let (sz, cz) = rz.to_radians().sin_cos();
    [
        Vec3::new(cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        Vec3::new(sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        Vec3::new(-sy, cy * sx, cy * cx),
    ]
}

impl Body {
    /// A full box lattice: every point, every spring of the stencil, resting with point
    /// `(0, 0, 0)` at the origin.
    pub fn lattice_box(lattice: Lattice, material: Material) -> Self {
        let active_count = lattice.len();
        Body {
            lattice,
            cells: None,
            links: Vec::new(),
            active: Vec::new(),
            active_count,
            table: None,
            material,
            origin: Vec3::ZERO,
            rotation: IDENTITY,
            skin: None,
            first: 0,
            contact: Derived::default(),
            clearance: Derived::default(),
        }
    }

    /// A lattice with holes: the cells `cells` keeps (one flag per cell, flat index
    /// `(i·cy + j)·cz + k` with `c = n − 1` cells per axis), with the springs of the rule in the
    /// module documentation. Fails when the lattice has an axis of one point, the flags do not
    /// match the cells, or no cell is kept. When every cell is kept the body is a full box.
    pub fn from_cells(
        lattice: Lattice,
        cells: Vec<bool>,
        material: Material,
    ) -> Result<Self, ModelError> {
        let [nx, ny, nz] = lattice.counts;
        if nx < 2 || ny < 2 || nz < 2 {
            return Err(ModelError::new(
                "a lattice with holes needs at least two points along each axis",
            ));
        }
        let cell_count = (nx - 1) * (ny - 1) * (nz - 1);
        if cells.len() != cell_count {
            return Err(ModelError::new(format!(
                "{} cell flags given for a lattice of {cell_count} cells",
                cells.len()
            )));
        }
        if !cells.contains(&false) {
            return Ok(Body::lattice_box(lattice, material));
        }
        if !cells.contains(&true) {
            return Err(ModelError::new("a body needs at least one kept cell"));
        }
        let links = link_bits(&lattice, &cells);
        let active = corners_of_kept(&lattice, &cells);
        let mut body = Body::lattice_box(lattice, material);
        body.active_count = active.iter().filter(|&&a| a).count();
        (body.cells, body.links, body.active) = (Some(cells), links, active);
        Ok(body)
    }

    /// The body of a closed, outward-wound triangle mesh voxelised with `cells` cells along its
    /// longest side ([`Voxels::from_mesh`], at most `max_cells` cells in all), carrying the mesh
    /// as its skin, resting where the mesh is.
    pub fn from_mesh(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        cells: usize,
        max_cells: usize,
        material: Material,
    ) -> Result<Self, ModelError> {
        let voxels = Voxels::from_mesh(vertices, triangles, cells, max_cells)?;
        let skin = Skin::embed(&voxels, vertices, triangles);
        Ok(Body::from_voxels(&voxels, material)?.with_skin(skin))
    }

    /// The body of the kept cells of `voxels`, resting where they are.
    pub fn from_voxels(voxels: &Voxels, material: Material) -> Result<Self, ModelError> {
        let body = Body::from_cells(voxels.lattice(), voxels.occupied.clone(), material)?;
        Ok(body.placed(voxels.origin, IDENTITY))
    }

    /// The same body with a material given independently of the resolution
    /// ([`Material::from_modulus`]): modulus (Pa), viscosity (Pa·s) and density (kg/m³) over
    /// [`Body::volume`].
    pub fn with_modulus(mut self, modulus: f64, viscosity: f64, density: f64) -> Self {
        let volume = self.volume();
        self.material = Material::from_modulus(
            modulus,
            viscosity,
            density,
            self.min_spacing(),
            volume,
            self.active_count,
        );
        self
    }

    /// The same body resting with lattice point `(0, 0, 0)` at `origin`, its rest shape turned by
    /// `rotation` about that point.
    pub fn placed(mut self, origin: Vec3, rotation: [Vec3; 3]) -> Self {
        self.origin = origin;
        self.rotation = rotation;
        self
    }

    /// The same body carrying `skin` (embedded in this lattice).
    pub fn with_skin(mut self, skin: Skin) -> Self {
        self.skin = Some(skin);
        self.contact = Derived::default();
        self.clearance = Derived::default();
        self
    }

    /// The surface other bodies touch: its samples and its signed distances at rest (see
    /// [`crate::model::contact_surface`]), computed on the first call.
    pub fn contact_surface(&self) -> &ContactSurface {
        self.contact
            .0
            .get_or_init(|| Arc::new(ContactSurface::new(self)))
    }

    /// Per lattice point, how far it rests outside the body's skin (m; 0 on or inside it, and
    /// for a point of no kept cell), computed on the first call: the walls, the plane and the
    /// obstacles take it off a point's depth, so that a skin touches them rather than the cage
    /// of cells around it (see [`crate::model::clearance`]). Empty for a body without a skin,
    /// or whose lattice points all rest on or inside it.
    pub fn clearance(&self) -> &[f64] {
        self.clearance
            .0
            .get_or_init(|| Arc::new(crate::model::clearance::rest_clearance(self)))
    }

    /// The lattice.
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The kept cells (`None` for a full box).
    pub fn cells(&self) -> Option<&[bool]> {
        self.cells.as_deref()
    }

    /// Number of cells that take part (all of a box).
    pub fn cell_count(&self) -> usize {
        match &self.cells {
            Some(c) => c.iter().filter(|&&k| k).count(),
            None => self
                .lattice
                .counts
                .iter()
                .map(|&n| n.saturating_sub(1))
                .product(),
        }
    }

    /// The solid's volume (m³): what its skin encloses at rest for a body made from a mesh (the
    /// divergence theorem over the closed mesh, [`enclosed_volume`]), else the volume of its
    /// cells. A density gives the body this volume's mass: the mesh's, not its cage's, which
    /// encloses it and is larger (an r = 0.3 m sphere in 10 cells across: 0.113 m³ against the
    /// cells' 0.156 m³).
    pub fn volume(&self) -> f64 {
        match &self.skin {
            Some(skin) => {
                let mut rest = vec![Vec3::ZERO; skin.len()];
                skin.positions(&self.lattice.rest_positions(), &mut rest);
                enclosed_volume(&rest, &skin.triangles)
            }
            None => {
                let h = self.lattice.spacing();
                self.cell_count() as f64 * h.x * h.y * h.z
            }
        }
    }

    /// True for a full box (no holes).
    pub fn is_full(&self) -> bool {
        self.cells.is_none()
    }

    /// Points in the lattice, active or not.
    pub fn len(&self) -> usize {
        self.lattice.len()
    }

    /// True when the lattice has no points.
    pub fn is_empty(&self) -> bool {
        self.lattice.is_empty()
    }

    /// Points that take part (the lattice's other points are placeholders that never move).
    pub fn active_count(&self) -> usize {
        self.active_count
    }

    /// Whether lattice point `p` (the body's own flat index) takes part.
    pub fn is_active(&self, p: usize) -> bool {
        self.active.is_empty() || self.active[p]
    }

    /// Per point whether it takes part; empty for a full box (every point does).
    pub fn active_mask(&self) -> &[bool] {
        &self.active
    }

    /// Per point the link bits of the stencil entries (see the module documentation); empty for
    /// a full box.
    pub(crate) fn links(&self) -> &[u16] {
        &self.links
    }

    /// The flat indices of this body's points in the model's arrays.
    pub fn points(&self) -> Range<usize> {
        self.first..self.first + self.len()
    }

    /// Total mass of the points that take part (kg).
    pub fn total_mass(&self) -> f64 {
        self.material.mass * self.active_count as f64
    }

    /// Rest position of lattice point `(i, j, k)` in the world (m).
    pub fn rest_position(&self, i: usize, j: usize, k: usize) -> Vec3 {
        let local = self.lattice.rest_position(i, j, k);
        let [r0, r1, r2] = self.rotation;
        if self.rotation == IDENTITY {
            // Exactly the lattice's positions plus the origin (the classic cube: i/7).
            return self.origin + local;
        }
        self.origin + Vec3::new(r0.dot(local), r1.dot(local), r2.dot(local))
    }

    /// Rest positions of all lattice points (m), in flat-index order.
    pub fn rest_positions(&self) -> Vec<Vec3> {
        (0..self.len())
            .map(|p| {
                let [i, j, k] = self.lattice.coords(p);
                self.rest_position(i, j, k)
            })
            .collect()
    }

    /// Calls `f(a, b, rest_len, kind, entry)` for every spring of the body (lattice indices of
    /// the body) with its rest length on the rest lattice and its stencil entry, in stencil
    /// order: first points in flat-index order, then stencil entries.
    fn for_each_lattice_spring(&self, mut f: impl FnMut(usize, usize, f64, SpringKind, usize)) {
        self.lattice
            .for_each_stencil_spring(|a, b, rest, kind, entry| {
                if self.is_linked(a, entry) {
                    f(a, b, rest, kind, entry);
                }
            });
    }

    /// Whether the lattice spring from point `a` along stencil entry `entry` is one of the
    /// body's (every one, where the body keeps no links).
    #[inline(always)]
    fn is_linked(&self, a: usize, entry: usize) -> bool {
        self.links.is_empty() || self.links[a] >> entry & 1 == 1
    }

    /// Calls `f` with every spring of the body (lattice indices of the body) and the values the
    /// force kernel uses for it, in stencil order: first points in flat-index order, then
    /// stencil entries.
    pub fn for_each_spring(&self, mut f: impl FnMut(&Spring)) {
        self.for_each_spring_entry(|spring, _| f(spring));
    }

    /// True when [`Body::for_each_spring_entry`] lists the same springs for `other` as for this
    /// body, at the same place in the model: the same lattice, springs, factors, stiffnesses and
    /// dampings (its mass, placement and skin may differ).
    pub(crate) fn has_springs_of(&self, other: &Body) -> bool {
        self.first == other.first
            && self.lattice == other.lattice
            && self.links == other.links
            && self.table == other.table
            && self.material.stiffness == other.material.stiffness
            && self.material.damping == other.material.damping
    }

    /// [`Body::for_each_spring`], also passing each spring's stencil entry (its index in
    /// [`crate::model::lattice::STENCIL`]).
    pub fn for_each_spring_entry(&self, mut f: impl FnMut(&Spring, usize)) {
        self.for_each_lattice_spring(|a, b, rest, kind, entry| {
            f(&self.spring(a, b, rest, kind, entry), entry);
        });
    }

    /// The springs of stencil entry `entry` alone, as [`Body::for_each_spring_entry`] lists
    /// them, in the order of their first point: the implicit solver lists its springs entry by
    /// entry, already in the order it keeps them in.
    pub(crate) fn for_each_spring_of_entry(&self, entry: usize, mut f: impl FnMut(&Spring)) {
        self.lattice
            .for_each_spring_of_entry(entry, |a, b, rest, kind| {
                if self.is_linked(a, entry) {
                    f(&self.spring(a, b, rest, kind, entry));
                }
            });
    }

    /// The spring from `a` to `b` of stencil entry `entry` and `kind`, `rest` long on the rest
    /// lattice, with the values the force kernel uses for it.
    #[inline(always)]
    fn spring(&self, a: usize, b: usize, rest: f64, kind: SpringKind, entry: usize) -> Spring {
        let m = &self.material;
        let (k, d) = (m.stiffness[kind as usize], m.damping[kind as usize]);
        match &self.table {
            None => Spring {
                a,
                b,
                kind,
                rest,
                stiffness: k,
                damping: d,
            },
            Some(table) => {
                // The same products the kernel forms.
                let s = table.get(self.len(), entry, a);
                Spring {
                    a,
                    b,
                    kind,
                    rest: rest * s.rest,
                    stiffness: k * s.stiffness,
                    damping: d * s.damping,
                }
            }
        }
    }

    /// Multiplies the rest length, stiffness and damping of every spring by the factors
    /// `scale(spring)` returns for it (given the spring's values so far), on top of any factors
    /// given before. Fails, changing nothing, on a factor that [`SpringScale::check`] refuses.
    /// When every factor ends at exactly 1 the body is as if never scaled.
    pub fn scale_springs(
        &mut self,
        mut scale: impl FnMut(&Spring) -> SpringScale,
    ) -> Result<(), ModelError> {
        let n = self.len();
        let mut table = match &self.table {
            Some(t) => t.clone().filled(n),
            None => SpringTable::ones(n),
        };
        let mut error = None;
        self.for_each_spring_entry(|spring, entry| {
            if error.is_some() {
                return;
            }
            let s = scale(spring);
            if let Err(e) = s.check() {
                error = Some(e);
                return;
            }
            let before = table.get(n, entry, spring.a);
            table.set(n, entry, spring.a, before.then(s));
        });
        if let Some(e) = error {
            return Err(e);
        }
        self.table = table.trimmed();
        Ok(())
    }

    /// The per-spring factors, when any differs from 1.
    pub fn spring_table(&self) -> Option<&SpringTable> {
        self.table.as_ref()
    }

    /// Calls `f` with every spring, as [`Body::for_each_spring`], and its factors
    /// ([`SpringScale::ONE`] for a body without a table).
    pub fn for_each_spring_scale(&self, mut f: impl FnMut(&Spring, SpringScale)) {
        let n = self.len();
        self.for_each_spring_entry(|spring, entry| {
            let scale = self
                .table
                .as_ref()
                .map_or(SpringScale::ONE, |t| t.get(n, entry, spring.a));
            f(spring, scale)
        });
    }

    /// The springs as flat arrays (lattice indices of the body), in [`Body::for_each_spring`]
    /// order; allocates.
    pub fn springs(&self) -> Springs {
        let mut springs = Springs::default();
        self.for_each_spring(|s| springs.push(s, 0));
        springs
    }

    /// Number of springs of each kind, indexed by `SpringKind as usize`.
    pub fn spring_count_by_kind(&self) -> [usize; 3] {
        if self.links.is_empty() {
            return self.lattice.spring_count_by_kind();
        }
        let mut counts = [0; 3];
        for &bits in &self.links {
            for (s, (_, kind)) in STENCIL.iter().enumerate() {
                counts[*kind as usize] += (bits >> s & 1) as usize;
            }
        }
        counts
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.spring_count_by_kind().iter().sum()
    }

    /// Triangles of the body's cage surface (two per face of a kept cell that no other kept cell
    /// shares), wound outward, as lattice indices of the body.
    pub fn surface_triangles(&self) -> Vec<[u32; 3]> {
        let Some(cells) = &self.cells else {
            return self.lattice.surface_triangles();
        };
        let [nx, ny, nz] = self.lattice.counts;
        let (cx, cy, cz) = (nx - 1, ny - 1, nz - 1);
        let kept = |i: isize, j: isize, k: isize| {
            (0..cx as isize).contains(&i)
                && (0..cy as isize).contains(&j)
                && (0..cz as isize).contains(&k)
                && cells[(i as usize * cy + j as usize) * cz + k as usize]
        };
        let idx = |i: usize, j: usize, k: usize| self.lattice.index(i, j, k) as u32;
        let mut tris = Vec::new();
        let mut quad = |q: [u32; 4]| {
            tris.push([q[0], q[1], q[2]]);
            tris.push([q[0], q[2], q[3]]);
        };
        for i in 0..cx {
            for j in 0..cy {
                for k in 0..cz {
                    if !cells[(i * cy + j) * cz + k] {
                        continue;
                    }
                    let (a, b, c) = (i as isize, j as isize, k as isize);
                    let (i1, j1, k1) = (i + 1, j + 1, k + 1);
                    if !kept(a - 1, b, c) {
                        quad([idx(i, j, k), idx(i, j, k1), idx(i, j1, k1), idx(i, j1, k)]);
                    }
                    if !kept(a + 1, b, c) {
                        quad([
                            idx(i1, j, k),
                            idx(i1, j1, k),
                            idx(i1, j1, k1),
                            idx(i1, j, k1),
                        ]);
                    }
                    if !kept(a, b - 1, c) {
                        quad([idx(i, j, k), idx(i1, j, k), idx(i1, j, k1), idx(i, j, k1)]);
                    }
                    if !kept(a, b + 1, c) {
                        quad([
                            idx(i, j1, k),
                            idx(i, j1, k1),
                            idx(i1, j1, k1),
                            idx(i1, j1, k),
                        ]);
                    }
                    if !kept(a, b, c - 1) {
                        quad([idx(i, j, k), idx(i, j1, k), idx(i1, j1, k), idx(i1, j, k)]);
                    }
                    if !kept(a, b, c + 1) {
                        quad([
                            idx(i, j, k1),
                            idx(i1, j, k1),
                            idx(i1, j1, k1),
                            idx(i, j1, k1),
                        ]);
                    }
                }
            }
        }
        tris
    }

    /// The smallest spacing of the lattice's points (m), over the axes with more than one point.
    pub fn min_spacing(&self) -> f64 {
        let h = self.lattice.spacing();
        [h.x, h.y, h.z]
            .into_iter()
            .filter(|&s| s > 0.0)
            .fold(f64::INFINITY, f64::min)
    }
}

/// Per point, whether it is a corner of a kept cell.
pub(crate) fn corners_of_kept(lattice: &Lattice, cells: &[bool]) -> Vec<bool> {
    let [nx, ny, nz] = lattice.counts;
    let (cy, cz) = (ny - 1, nz - 1);
    let mut active = vec![false; nx * ny * nz];
    for i in 0..nx - 1 {
        for j in 0..cy {
            for k in 0..cz {
                if cells[(i * cy + j) * cz + k] {
                    for c in 0..8 {
                        let (a, b, d) = (c >> 2 & 1, c >> 1 & 1, c & 1);
                        active[lattice.index(i + a, j + b, k + d)] = true;
                    }
                }
            }
        }
    }
    active
}

/// Per point the link bits of the rule in the module documentation.
fn link_bits(lattice: &Lattice, cells: &[bool]) -> Vec<u16> {
    let [nx, ny, nz] = lattice.counts;
    let c = [nx - 1, ny - 1, nz - 1];
    // Whether cell (i, j, k) exists and is kept; coordinates may be out of range.
    let kept = |cell: [isize; 3]| {
        (0..3).all(|a| (0..c[a] as isize).contains(&cell[a]))
            && cells[(cell[0] as usize * c[1] + cell[1] as usize) * c[2] + cell[2] as usize]
    };
    // A structural edge from p along axis `a`: any of the cells around it.
    let edge = |p: [isize; 3], a: usize| {
        let (b, d) = ((a + 1) % 3, (a + 2) % 3);
        (0..4).any(|n| {
            let mut cell = p;
            cell[b] -= n & 1;
            cell[d] -= n >> 1 & 1;
            kept(cell)
        })
    };
    let n = [nx as isize, ny as isize, nz as isize];
    let mut links = vec![0u16; lattice.len()];
    for (point, bits) in links.iter_mut().enumerate() {
        let p = lattice.coords(point).map(|v| v as isize);
        for (s, &(d, kind)) in STENCIL.iter().enumerate() {
            let q = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
            if (0..3).any(|a| !(0..n[a]).contains(&q[a])) {
                continue;
            }
            let lower = [p[0].min(q[0]), p[1].min(q[1]), p[2].min(q[2])];
            let moving: Vec<usize> = (0..3).filter(|&a| d[a] != 0).collect();
            let exists = match (kind, moving.len()) {
                (SpringKind::Structural, _) => edge(p, moving[0]),
                (SpringKind::Bend, _) => {
                    let a = moving[0];
                    let mut mid = p;
                    mid[a] += 1;
                    edge(p, a) && edge(mid, a)
                }
                (SpringKind::Shear, 2) => {
                    // The face spanned by the two moving axes; the cells on either side of it.
                    let fixed = (0..3).find(|a| d[*a] == 0).expect("one fixed axis");
                    (0..2).any(|side| {
                        let mut cell = lower;
                        cell[fixed] -= side;
                        kept(cell)
                    })
                }
                (SpringKind::Shear, _) => kept(lower),
            };
            if exists {
                *bits |= 1 << s;
            }
        }
    }
    links
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With every cell kept the rule gives exactly the full stencil.
    #[test]
    fn all_cells_kept_is_the_full_stencil() {
        let lattice = Lattice::new([4, 3, 5], Vec3::new(1.0, 1.0, 2.0));
        let cells = vec![true; 3 * 2 * 4];
        let full = Body::lattice_box(lattice.clone(), Material::classic());
        let links = link_bits(&lattice, &cells);
        let mut n = 0;
        full.lattice().for_each_stencil_spring(|a, _, _, _, s| {
            assert_eq!(links[a] >> s & 1, 1);
            n += 1;
        });
        let set: u32 = links.iter().map(|b| b.count_ones()).sum();
        assert_eq!(set as usize, n);
    }

    /// One kept cell of a 3×3×3 lattice: 12 edges, 12 face diagonals, 4 body diagonals, no
    /// bend springs, 8 points.
    #[test]
    fn a_single_cell_has_its_own_springs() {
        let lattice = Lattice::new([3, 3, 3], Vec3::new(1.0, 1.0, 1.0));
        let mut cells = vec![false; 8];
        cells[7] = true;
        let body = Body::from_cells(lattice, cells, Material::classic()).unwrap();
        assert_eq!(body.spring_count_by_kind(), [12, 16, 0]);
        assert_eq!(body.active_count(), 8);
        assert_eq!(body.cell_count(), 1);
        assert_eq!(body.surface_triangles().len(), 12);
    }
}
