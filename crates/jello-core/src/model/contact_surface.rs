//! The surfaces bodies touch each other with. Per body:
//!
//! - its **samples**: the points of its surface that press on other bodies, each embedded in one
//!   of its cells by its place there, so that it moves with the cell's eight corners: for a body
//!   made from a mesh, the skin's vertices and points along its edges and inside its triangles,
//!   at most a cell apart; else the lattice points on its cage's surface (every lattice point of
//!   a body without cells, which has no inside);
//! - the **signed distance** at rest from each of its lattice points to its surface (its skin,
//!   else its cage's surface): negative inside, interpolated trilinearly over a cell as the cell
//!   deforms, so that "how deep is this point inside that body, and which way is out" is a
//!   lookup in the cell the point is in.
//!
//! A sample of one body inside a cell of another where that body's interpolated distance is
//! negative touches it: its depth is the distance over the gradient's length (the distance to
//! the zero level, to first order, as the cell is deformed), its normal the gradient's direction.
//! So bodies touch skin to skin, at any resolution, rather than a lattice spacing apart.

use crate::model::body::Body;
use crate::model::lattice::Lattice;
use crate::model::voxel::ray_crossing;
use crate::vec3::Vec3;

/// Points of the distance grid per lattice spacing, at the least. The interpolated surface strays
/// from a skin (inward where it is convex): at the edges between a mesh's faces by about a
/// quarter of the grid's spacing times the angle between the faces, over a smooth curve by about
/// the spacing squared over the curvature's radius. On a pile of 0.4 m shapes of 6 cells the
/// skins went 1.7–2.8 mm (2.5–4.2 % of a cell) into each other at 2 and 2.1–2.5 mm at 3
/// (whatever the collision stiffness), 1.0–1.9 mm (1.5–2.8 %) at 4 as the lattices fell on the
/// meshes; so a skin that this grid rounds by more than [`ROUNDING`] gets one [`FINE_REFINE`]
/// times as fine. A body one cell across still has points in its middle, below its surface.
pub const REFINE: usize = 4;

/// Points per lattice spacing of the distance grid of a skin that the grid at [`REFINE`] rounds
/// by more than [`ROUNDING`] (when it has at most [`GRID_POINTS`] points). Every shape of
/// `pile.toml` (sphere, ring, L, capsule) gets it: at rest the skins then go 0.6 mm (0.9 % of a
/// cell) into each other, at most 0.9 mm (1.3 %) with the shapes shifted, turned or at 7 cells
/// (up to 1.9 mm, 2.8 %, at [`REFINE`]); the pile takes 0.4 s and 10 MB more to load, and no
/// longer a step.
pub const FINE_REFINE: usize = 2 * REFINE;
const _: () = assert!(
    FINE_REFINE % REFINE == 0,
    "the finer grid is made from the coarser"
);

/// How far the distance grid's zero level may stray from a skin, as a fraction of the body's
/// finest lattice spacing, before the body gets a grid [`FINE_REFINE`] times as fine: measured at
/// the skin's vertices, edges' middles and triangles' centres (each one's interpolated distance
/// over its gradient's length).
pub const ROUNDING: f64 = 0.01;

/// The most points a grid refined past [`REFINE`] may have (8 bytes each, 4 more on the GPU):
/// a larger body keeps its grid at [`REFINE`].
pub const GRID_POINTS: usize = 1 << 21;

/// The eight corners of a cell as offsets `(a, b, c)`, in the order of `weights`.
pub const CORNERS: [[usize; 3]; 8] = [
    [0, 0, 0],
    [0, 0, 1],
    [0, 1, 0],
    [0, 1, 1],
    [1, 0, 0],
    [1, 0, 1],
    [1, 1, 0],
    [1, 1, 1],
];

/// The trilinear weights of the corners of a cell (in the order of [`CORNERS`]) at its place
/// `(u, v, w)`.
#[inline]
pub(crate) fn weights([u, v, w]: [f64; 3]) -> [f64; 8] {
    let f = |s: usize, t: f64| if s == 1 { t } else { 1.0 - t };
    map8(CORNERS, |[a, b, c]| f(a, u) * f(b, v) * f(c, w))
}

/// `array.map(f)` for 8 entries, written out: `map` may be left a call with its arrays copied
/// through memory, and these run for every contact.
#[inline(always)]
pub(crate) fn map8<T: Copy, U>(a: [T; 8], mut f: impl FnMut(T) -> U) -> [U; 8] {
    [
        f(a[0]),
        f(a[1]),
        f(a[2]),
        f(a[3]),
        f(a[4]),
        f(a[5]),
        f(a[6]),
        f(a[7]),
    ]
}

/// [`map8`] for 3 entries.
#[inline(always)]
pub(crate) fn map3<T: Copy, U>(a: [T; 3], mut f: impl FnMut(T) -> U) -> [U; 3] {
    [f(a[0]), f(a[1]), f(a[2])]
}

/// The derivatives of the trilinear weights along u, v and w, per corner.
#[inline]
fn weight_derivatives([u, v, w]: [f64; 3]) -> [[f64; 3]; 8] {
    let f = |s: usize, t: f64| if s == 1 { t } else { 1.0 - t };
    let d = |s: usize| if s == 1 { 1.0 } else { -1.0 };
    map8(CORNERS, |[a, b, c]| {
        [
            d(a) * f(b, v) * f(c, w),
            f(a, u) * d(b) * f(c, w),
            f(a, u) * f(b, v) * d(c),
        ]
    })
}

/// A point of a body's surface, embedded in one of its cells: the cell's lower corner (a
/// lattice index of the body) and the point's place in it, each coordinate in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub(crate) corner: u32,
    pub(crate) local: [f64; 3],
}

/// What contact needs of one body's surface (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct ContactSurface {
    /// The points that press on other bodies.
    pub(crate) samples: Vec<Sample>,
    /// The signed distance at rest to the body's surface (m; negative inside; clamped two cell
    /// diagonals deep) on a grid `refine` times as fine as the lattice (points per axis
    /// `refined`), so that a body one cell thick still has an inside; 0 outside its kept cells.
    pub(crate) distance: Vec<f64>,
    pub(crate) refined: [usize; 3],
    /// Points of the distance grid per lattice spacing: [`REFINE`], or [`FINE_REFINE`] for a
    /// skin the coarser grid rounds by more than [`ROUNDING`].
    pub(crate) refine: usize,
    /// The kept cells, as the lattice indices of their lower corners, in flat order.
    pub(crate) cells: Vec<u32>,
    /// Flat-index offsets of a cell's corners from its lower corner, in the order of
    /// [`CORNERS`].
    pub(crate) offsets: [usize; 8],
}

impl Sample {
    /// The lattice index (of its body) of the lower corner of the cell the sample is in.
    pub fn corner(&self) -> u32 {
        self.corner
    }

    /// The sample's place `(u, v, w)` in its cell, each in `[0, 1]`.
    pub fn local(&self) -> [f64; 3] {
        self.local
    }
}

impl ContactSurface {
    /// How many points of the surface press on other bodies.
    pub fn sample_count(&self) -> usize {
        self.samples.len()
    }

    /// The points of the surface that press on other bodies.
    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }

    /// The kept cells, as the lattice indices (of the body) of their lower corners.
    pub fn cells(&self) -> &[u32] {
        &self.cells
    }

    /// Lattice-index offsets of a cell's eight corners from its lower corner, in the order of
    /// [`CORNERS`].
    pub fn corner_offsets(&self) -> [usize; 8] {
        self.offsets
    }

    /// The signed distance at rest to the surface (m) on its grid [`ContactSurface::refine`]
    /// times as fine as the lattice, and that grid's points per axis (flat index
    /// `(i·ry + j)·rz + k`; lattice point `(i, j, k)` is grid point `refine·(i, j, k)`); empty
    /// for a body without cells.
    pub fn distance_grid(&self) -> (&[f64], [usize; 3]) {
        (&self.distance, self.refined)
    }

    /// Points of the distance grid per lattice spacing: [`REFINE`], or [`FINE_REFINE`] for a
    /// skin that grid's interpolation rounds by more than [`ROUNDING`] of a cell (when the finer
    /// grid has at most [`GRID_POINTS`] points).
    pub fn refine(&self) -> usize {
        self.refine
    }

    /// The interpolated distance in the cell whose lower corner is lattice point `corner`, at
    /// its place `uvw`, and its gradient over `(u, v, w)`.
    #[inline]
    pub(crate) fn distance_in(&self, corner: [usize; 3], uvw: [f64; 3]) -> (f64, [f64; 3]) {
        interpolate(&self.distance, self.refined, self.refine, corner, uvw)
    }

    /// [`ContactSurface::distance_in`], the same bits, with the distances at the corners of
    /// the grid's sub-cell that holds `uvw` kept in `cache`: a point that touches is found in
    /// the same sub-cell step after step, and the grid, read at random, is not in the caches of
    /// the processor by the time it is asked again (a third of a settled pile's contact pass
    /// went to that wait).
    #[inline]
    pub(crate) fn distance_cached(
        &self,
        corner: [usize; 3],
        uvw: [f64; 3],
        cache: &mut DistanceCache,
    ) -> (f64, [f64; 3]) {
        let (base, t) = sub_cell(self.refined, self.refine, corner, uvw);
        if cache.base != base as u64 {
            let [_, ry, rz] = self.refined;
            cache.values = map8(CORNERS, |[a, b, c]| {
                self.distance[base + (a * ry + b) * rz + c]
            });
            cache.base = base as u64;
        }
        interpolate_values(&cache.values, self.refine, t)
    }

    /// The surface of `body`.
    pub(crate) fn new(body: &Body) -> Self {
        let lattice = body.lattice();
        let [nx, ny, nz] = lattice.counts;
        let kept = |i: usize, j: usize, k: usize| match body.cells() {
            Some(cells) => cells[(i * (ny - 1) + j) * (nz - 1) + k],
            None => true,
        };
        let mut cells = Vec::new();
        if nx > 1 && ny > 1 && nz > 1 {
            for i in 0..nx - 1 {
                for j in 0..ny - 1 {
                    for k in 0..nz - 1 {
                        if kept(i, j, k) {
                            cells.push(lattice.index(i, j, k) as u32);
                        }
                    }
                }
            }
        }
        if cells.is_empty() {
            // A body without volume (a point, a row, a sheet one point thick): its points press
            // on other bodies, each a sample on its own (all eight "corners" the point itself),
            // and nothing is inside it.
            return ContactSurface {
                samples: (0..lattice.len() as u32)
                    .map(|corner| Sample {
                        corner,
                        local: [0.0; 3],
                    })
                    .collect(),
                offsets: [0; 8],
                refine: REFINE,
                ..ContactSurface::default()
            };
        }
        let offsets = CORNERS.map(|[a, b, c]| (a * ny + b) * nz + c);
        // The surface at rest, in the lattice's own frame (placement turns and moves it, which
        // changes no distance): the skin, else the cage's surface.
        let rest = lattice.rest_positions();
        let (vertices, triangles, samples) = match &body.skin {
            Some(skin) => {
                let mut vertices = vec![Vec3::ZERO; skin.len()];
                skin.positions(&rest, &mut vertices);
                let mut samples: Vec<Sample> = (skin.corner.iter().zip(&skin.local))
                    .map(|(&corner, &local)| Sample { corner, local })
                    .collect();
                // Edges and triangles longer than a cell get points along and inside them too,
                // a cell apart at most, so that another body's edge cannot cross a face between
                // its vertices unseen. Each edge once (it is shared by two triangles).
                let h = lattice.spacing();
                let spacing = h.x.min(h.y).min(h.z);
                let parts = |longest: f64| (longest / spacing).ceil().max(1.0) as usize;
                let mut edges: Vec<[u32; 2]> = (skin.triangles.iter())
                    .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
                    .map(|[a, b]| [a.min(b), a.max(b)])
                    .collect();
                edges.sort_unstable();
                edges.dedup();
                for [a, b] in edges {
                    let (a, b) = (vertices[a as usize], vertices[b as usize]);
                    let n = parts((b - a).length());
                    for m in 1..n {
                        let p = a + (b - a) * (m as f64 / n as f64);
                        samples.extend(embed(lattice, p, &kept));
                    }
                }
                for t in &skin.triangles {
                    let [a, b, c] = t.map(|v| vertices[v as usize]);
                    let n = parts((b - a).length().max((c - b).length()).max((a - c).length()));
                    // Strictly inside: the vertices and edges have theirs.
                    for i in 1..n {
                        for j in 1..n - i {
                            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                            let p = a + (b - a) * u + (c - a) * v;
                            samples.extend(embed(lattice, p, &kept));
                        }
                    }
                }
                (vertices, skin.triangles.clone(), samples)
            }
            None => {
                let triangles = body.surface_triangles();
                let mut on_surface = vec![false; lattice.len()];
                for t in &triangles {
                    for &p in t {
                        on_surface[p as usize] = true;
                    }
                }
                let samples = (0..lattice.len())
                    .filter(|&p| on_surface[p])
                    .filter_map(|p| cage_sample(lattice, p, &kept))
                    .collect();
                (rest.clone(), triangles, samples)
            }
        };
        let reach = 2.0 * lattice.spacing().length();
        let grid = |refine, coarse: Option<&Coarse>| {
            signed_distances(
                lattice, &cells, &vertices, &triangles, reach, refine, coarse,
            )
        };
        let (mut refine, (mut refined, mut distance)) = (REFINE, grid(REFINE, None));
        // A cage's faces lie on the lattice's planes, where the grid is exact; a skin that curves
        // or has edges between them is rounded, and a finer grid rounds it less.
        if body.skin.is_some() && grid_points(lattice.counts, FINE_REFINE) <= GRID_POINTS {
            let h = lattice.spacing();
            let probes = skin_probes(lattice, &vertices, &triangles, &kept);
            let rounding = rounding(&probes, &distance, refined, REFINE, h);
            if rounding > ROUNDING * h.x.min(h.y).min(h.z) {
                let coarse = Coarse {
                    distance: &distance,
                    refined,
                    factor: FINE_REFINE / REFINE,
                    band: (h * (1.0 / REFINE as f64)).length(),
                };
                refine = FINE_REFINE;
                (refined, distance) = grid(refine, Some(&coarse));
            }
        }
        ContactSurface {
            samples,
            distance,
            refined,
            refine,
            cells,
            offsets,
        }
    }
}

/// A point `p` of the body at rest (the lattice's frame) as a sample: in the kept cell that
/// holds it (the first, where it is on a face between cells), `None` when none does.
fn embed(
    lattice: &Lattice,
    p: Vec3,
    kept: &impl Fn(usize, usize, usize) -> bool,
) -> Option<Sample> {
    let h = lattice.spacing().to_array();
    let q = p.to_array();
    let cells = lattice.counts.map(|n| n.saturating_sub(1));
    // The cells along each axis that hold the coordinate: one, or two on a plane between.
    let candidates = |a: usize| {
        let x = q[a] / h[a];
        let i = (x.floor().max(0.0) as usize).min(cells[a].saturating_sub(1));
        let on_plane = x == x.floor() && i > 0 && x.floor() as usize == i;
        if on_plane {
            [i, i - 1]
        } else {
            [i, i]
        }
    };
    let (ci, cj, ck) = (candidates(0), candidates(1), candidates(2));
    for &i in &ci {
        for &j in &cj {
            for &k in &ck {
                if kept(i, j, k) {
                    let local = [0, 1, 2].map(|a| {
                        let c = [i, j, k][a];
                        ((q[a] - c as f64 * h[a]) / h[a]).clamp(0.0, 1.0)
                    });
                    return Some(Sample {
                        corner: lattice.index(i, j, k) as u32,
                        local,
                    });
                }
            }
        }
    }
    None
}

/// Lattice point `p` as a sample: embedded in the first kept cell that has it as a corner.
fn cage_sample(
    lattice: &Lattice,
    p: usize,
    kept: &impl Fn(usize, usize, usize) -> bool,
) -> Option<Sample> {
    let [i, j, k] = lattice.coords(p);
    let [nx, ny, nz] = lattice.counts;
    CORNERS.iter().find_map(|&[a, b, c]| {
        let (ci, cj, ck) = (i.checked_sub(a)?, j.checked_sub(b)?, k.checked_sub(c)?);
        if ci + 1 >= nx || cj + 1 >= ny || ck + 1 >= nz || !kept(ci, cj, ck) {
            return None;
        }
        Some(Sample {
            corner: lattice.index(ci, cj, ck) as u32,
            local: [a as f64, b as f64, c as f64],
        })
    })
}

/// The distance on a grid `refine` times as fine as the lattice (points per axis `refined`),
/// interpolated in the cell whose lower corner is lattice point `(ci, cj, ck)` at its place
/// `uvw`, and its gradient over `(u, v, w)`: trilinear on the grid's sub-cell that holds `uvw`.
#[inline]
fn interpolate(
    distance: &[f64],
    refined: [usize; 3],
    refine: usize,
    corner: [usize; 3],
    uvw: [f64; 3],
) -> (f64, [f64; 3]) {
    let (base, t) = sub_cell(refined, refine, corner, uvw);
    let [_, ry, rz] = refined;
    let d = map8(CORNERS, |[a, b, c]| distance[base + (a * ry + b) * rz + c]);
    interpolate_values(&d, refine, t)
}

/// The distances at the corners of a sub-cell of a distance grid, kept (see
/// [`ContactSurface::distance_cached`]): the flat index of its lower corner in the grid, and
/// the values at its corners in the order of [`CORNERS`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct DistanceCache {
    base: u64,
    values: [f64; 8],
}

impl DistanceCache {
    /// No sub-cell kept.
    pub(crate) const EMPTY: DistanceCache = DistanceCache {
        base: u64::MAX,
        values: [0.0; 8],
    };
}

/// The sub-cell of a distance grid `refine` times as fine as the lattice (points per axis
/// `refined`) that holds place `uvw` of the cell whose lower corner is lattice point
/// `(ci, cj, ck)`: the flat index of its lower corner, and the place in it.
#[inline]
fn sub_cell(
    refined: [usize; 3],
    refine: usize,
    [ci, cj, ck]: [usize; 3],
    uvw: [f64; 3],
) -> (usize, [f64; 3]) {
    let r = refine as f64;
    // (A cast truncates towards zero and takes what is below zero, or not a number, to 0: the
    // floor's own result here, without the library call `floor` is on the baseline target.)
    let sub = map3(uvw, |u| ((u * r) as usize).min(refine - 1));
    let t = map3([0, 1, 2], |a| uvw[a] * r - sub[a] as f64);
    let [_, ry, rz] = refined;
    let base = ((refine * ci + sub[0]) * ry + refine * cj + sub[1]) * rz + refine * ck + sub[2];
    (base, t)
}

/// The trilinear interpolation over a sub-cell of a distance grid `refine` times as fine as
/// the lattice, from the distances `d` at its corners, at its place `t`; and its gradient over
/// the cell's `(u, v, w)`.
#[inline]
fn interpolate_values(d: &[f64; 8], refine: usize, t: [f64; 3]) -> (f64, [f64; 3]) {
    let r = refine as f64;
    let w = weights(t);
    let phi = d.iter().zip(w).map(|(d, w)| d * w).sum();
    let mut g = [0.0; 3];
    for (d, dw) in d.iter().zip(weight_derivatives(t)) {
        for (g, dw) in g.iter_mut().zip(dw) {
            *g += d * dw * r;
        }
    }
    (phi, g)
}

/// The points of a distance grid `refine` times as fine as a lattice of `counts` points per axis.
fn grid_points(counts: [usize; 3], refine: usize) -> usize {
    (counts.iter()).fold(1usize, |p, &n| {
        p.saturating_mul(refine.saturating_mul(n.saturating_sub(1)) + 1)
    })
}

/// How far the zero level of the interpolated distance `distance` (a grid `refine` times as
/// fine as a lattice of spacing `h`, points per axis `refined`) strays from the skin at most:
/// the largest interpolated distance at `probes`, points of the skin (see `skin_probes`), over
/// its gradient's length.
fn rounding(
    probes: &[([usize; 3], [f64; 3])],
    distance: &[f64],
    refined: [usize; 3],
    refine: usize,
    h: Vec3,
) -> f64 {
    (probes.iter())
        .map(|&(corner, local)| {
            let (phi, g) = interpolate(distance, refined, refine, corner, local);
            let slope = Vec3::new(g[0] / h.x, g[1] / h.y, g[2] / h.z).length();
            // A distance's gradient is 1 long; interpolated across a crease it can be shorter.
            phi.abs() / slope.max(0.5)
        })
        .fold(0.0, f64::max)
}

/// Points of the skin `vertices` / `triangles` (in the lattice's frame) to measure the
/// interpolated distance's rounding at: its vertices, its edges' middles and its triangles'
/// centres, each as the cell it is in (lower corner's coordinates) and its place there.
fn skin_probes(
    lattice: &Lattice,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    kept: &impl Fn(usize, usize, usize) -> bool,
) -> Vec<([usize; 3], [f64; 3])> {
    let points = (vertices.iter().copied()).chain(triangles.iter().flat_map(|&[a, b, c]| {
        let [a, b, c] = [a, b, c].map(|v| vertices[v as usize]);
        [
            (a + b) * 0.5,
            (b + c) * 0.5,
            (c + a) * 0.5,
            (a + b + c) * (1.0 / 3.0),
        ]
    }));
    points
        .filter_map(|p| embed(lattice, p, kept))
        .map(|s| (lattice.coords(s.corner as usize), s.local))
        .collect()
}

/// A distance grid `factor` times as coarse as the one being made, to skip the points far from
/// the surface: its interpolated distance is within a sub-cell's diagonal of the true one (a
/// distance changes by at most the way moved), so where it is further than `band` (that
/// diagonal) from 0, its sign is right and its value close enough for a point no contact rests
/// at; the grid's points it has itself take its values exactly.
pub(crate) struct Coarse<'a> {
    distance: &'a [f64],
    refined: [usize; 3],
    factor: usize,
    band: f64,
}

impl Coarse<'_> {
    /// The coarse grid's interpolated distance at point `(i, j, k)` of the finer grid, when it
    /// is further than the band from the surface.
    fn far_from_surface(&self, fine: [usize; 3]) -> Option<f64> {
        let m = self.factor;
        let [_, cy, cz] = self.refined;
        // The coarse sub-cell holding the point (the last along an axis for a point on its end).
        let lower = map3([0, 1, 2], |a| (fine[a] / m).min(self.refined[a] - 2));
        let t = map3([0, 1, 2], |a| (fine[a] - lower[a] * m) as f64 / m as f64);
        let w = weights(t);
        let phi: f64 = (CORNERS.iter().zip(w))
            .map(|(&[a, b, c], w)| {
                let at = ((lower[0] + a) * cy + lower[1] + b) * cz + lower[2] + c;
                self.distance[at] * w
            })
            .sum();
        (phi.abs() > self.band).then_some(phi)
    }
}

/// The signed distance (m) to the closed surface `vertices` / `triangles` at the points of a
/// grid `refine` times as fine as `lattice` ([`REFINE`] or [`FINE_REFINE`] for contacts, 1 for
/// the lattice points themselves), in the kept cells `cells` (their lower corners' lattice
/// indices): negative inside; `−reach` for a point further than `reach` from the surface
/// (inside: every point of a kept cell is within a cell's diagonal of the solid); 0 outside the
/// kept cells. Returns the grid's points per axis and the distances.
pub(crate) fn signed_distances(
    lattice: &Lattice,
    cells: &[u32],
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    reach: f64,
    refine: usize,
    coarse: Option<&Coarse>,
) -> ([usize; 3], Vec<f64>) {
    let refined = lattice.counts.map(|n| refine * n.saturating_sub(1) + 1);
    let [rx, ry, rz] = refined;
    let index = |i: usize, j: usize, k: usize| (i * ry + j) * rz + k;
    let h = lattice.spacing() * (1.0 / refine as f64);
    let at =
        |i: usize, j: usize, k: usize| Vec3::new(i as f64 * h.x, j as f64 * h.y, k as f64 * h.z);
    // The grid's points in kept cells.
    let mut used = vec![false; rx * ry * rz];
    for &c in cells {
        let [ci, cj, ck] = lattice.coords(c as usize).map(|x| refine * x);
        for i in ci..=ci + refine {
            for j in cj..=cj + refine {
                for k in ck..=ck + refine {
                    used[index(i, j, k)] = true;
                }
            }
        }
    }
    // Unsigned distance, through a grid of the triangles' boxes with cells of half `reach`,
    // searched in shells about a point's own until the rest are further than the nearest found
    // (or than `reach`); each triangle's box kept to pass over those further than that too.
    let mut distance = vec![0.0; rx * ry * rz];
    // The nearest triangle is sought within `search`: `reach`, or, where a coarser grid gives
    // the points further from the surface than its band, within twice the band of the rest.
    let search = coarse.map_or(reach, |c| (2.0 * c.band).min(reach));
    let inv = 2.0 / search;
    let corners: Vec<[Vec3; 3]> = (triangles.iter())
        .map(|t| t.map(|v| vertices[v as usize]))
        .collect();
    let boxes: Vec<[Vec3; 2]> = (corners.iter())
        .map(|&[a, b, c]| [a.min(b).min(c), a.max(b).max(c)])
        .collect();
    // The buckets cover the lattice's box (the grid's points are in it) and one more on each
    // side; a triangle reaching further is entered at the edge (its box still decides).
    let h_lattice = lattice.spacing().to_array();
    let span = [0, 1, 2].map(|a| {
        let size = h_lattice[a] * lattice.counts[a].saturating_sub(1) as f64;
        (size * inv).floor() as i64 + 3
    });
    let cell_of = |p: Vec3| {
        let c = (p * inv).to_array();
        [0, 1, 2].map(|a| (c[a].floor() as i64 + 1).clamp(0, span[a] - 1))
    };
    let flat = |c: [i64; 3]| ((c[0] * span[1] + c[1]) * span[2] + c[2]) as usize;
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); (span[0] * span[1] * span[2]) as usize];
    for (t, [lo, hi]) in boxes.iter().enumerate() {
        let (lo, hi) = (cell_of(*lo), cell_of(*hi));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    buckets[flat([x, y, z])].push(t as u32);
                }
            }
        }
    }
    // The triangles each row of the grid along x may cross (by their boxes, a row wider on
    // each side: the crossing test itself decides).
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); ry * rz];
    for (t, [lo, hi]) in boxes.iter().enumerate() {
        let span = |lo: f64, hi: f64, h: f64, n: usize| {
            let first = ((lo / h).floor() as i64 - 1).clamp(0, n as i64 - 1) as usize;
            let last = ((hi / h).ceil() as i64 + 1).clamp(0, n as i64 - 1) as usize;
            first..=last
        };
        for j in span(lo.y, hi.y, h.y, ry) {
            for k in span(lo.z, hi.z, h.z, rz) {
                rows[j * rz + k].push(t as u32);
            }
        }
    }
    // The buckets about a point's own, shell by shell (0: its own; `r`: those `r` buckets away
    // along some axis, whose triangles are at least `r − 1` buckets from the point). Two
    // shells cover `search`.
    const SHELLS: i64 = 2;
    let shells: Vec<Vec<[i64; 3]>> = (0..=SHELLS)
        .map(|r| {
            let mut shell = Vec::new();
            for x in -r..=r {
                for y in -r..=r {
                    for z in -r..=r {
                        if x.abs().max(y.abs()).max(z.abs()) == r {
                            shell.push([x, y, z]);
                        }
                    }
                }
            }
            shell
        })
        .collect();
    let bucket = search / 2.0;
    // How far `q` is from bucket `key` (0 where it is in it), squared: bucket `k` along an axis
    // holds from `(k − 1)·bucket` to `k·bucket`, the first and last one beyond as well.
    let bucket_distance_squared = |key: [i64; 3], q: Vec3| {
        let q = q.to_array();
        (0..3)
            .map(|a| {
                let lo = if key[a] == 0 {
                    f64::NEG_INFINITY
                } else {
                    (key[a] - 1) as f64 * bucket
                };
                let hi = if key[a] == span[a] - 1 {
                    f64::INFINITY
                } else {
                    key[a] as f64 * bucket
                };
                let out = (lo - q[a]).max(q[a] - hi).max(0.0);
                out * out
            })
            .sum::<f64>()
    };
    let mut crossings: Vec<(f64, i32)> = Vec::new();
    for j in 0..ry {
        for k in 0..rz {
            if !(0..rx).any(|i| used[index(i, j, k)]) {
                continue;
            }
            // Sign: a ray along +x through the row, counting the crossings past each point (a
            // point exactly on the surface has distance 0, whatever its sign).
            let (y, z) = (j as f64 * h.y, k as f64 * h.z);
            crossings.clear();
            crossings.extend(
                (rows[j * rz + k].iter())
                    .filter_map(|&t| ray_crossing(vertices, triangles[t as usize], y, z)),
            );
            for i in 0..rx {
                let p = index(i, j, k);
                if !used[p] {
                    continue;
                }
                if let Some(far) = coarse.and_then(|c| c.far_from_surface([i, j, k])) {
                    distance[p] = far;
                    continue;
                }
                let q = at(i, j, k);
                let c = cell_of(q);
                let mut best = f64::INFINITY;
                for (r, shell) in shells.iter().enumerate() {
                    // Every triangle not yet seen is at least `r − 1` buckets away.
                    let beyond = (r as f64 - 1.0).max(0.0) * bucket;
                    if beyond * beyond >= best || beyond >= search {
                        break;
                    }
                    for d in shell {
                        let key = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                        if (0..3).any(|a| key[a] < 0 || key[a] >= span[a]) {
                            continue;
                        }
                        // A bucket further than the nearest triangle found holds none nearer:
                        // such a triangle's nearest point is in a bucket at most that far.
                        if bucket_distance_squared(key, q) >= best {
                            continue;
                        }
                        for &t in &buckets[flat(key)] {
                            let [lo, hi] = boxes[t as usize];
                            let outside = (lo - q).max(q - hi).max(Vec3::ZERO);
                            if outside.length_squared() >= best {
                                continue;
                            }
                            let [a, b, c] = corners[t as usize];
                            best = best.min(point_triangle_distance_squared(q, a, b, c));
                        }
                    }
                }
                let unsigned = best.sqrt().min(reach);
                let winding: i32 = crossings.iter().filter(|c| c.0 > q.x).map(|c| c.1).sum();
                distance[p] = if winding != 0 { -unsigned } else { unsigned };
            }
        }
    }
    (refined, distance)
}

/// The squared distance from `p` to the triangle `a b c` (Ericson, "Real-Time Collision
/// Detection", 5.1.5: the closest point by the region of the triangle it falls in).
fn point_triangle_distance_squared(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return (p - (a + ab * t)).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return (p - (a + ac * t)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * t)).length_squared();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length_squared()
}

/// Where a point of another body is inside a deformed cell: its place `(u, v, w)` in the cell
/// (found by Newton's method on the trilinear map), and the inverse transpose of the map's
/// derivative there (to turn gradients over `(u, v, w)` into gradients in space). `None` when it
/// is not in the cell (by more than a rounding) or the cell is degenerate there.
pub(crate) fn locate(corners: &[Vec3; 8], p: Vec3) -> Option<([f64; 3], [Vec3; 3])> {
    locate_from(corners, p, [0.5; 3])
}

/// [`locate`], with Newton's method started at `start` (a place in the cell or near it: where
/// the point would be if the cell were as at rest, say) instead of the cell's middle.
pub(crate) fn locate_from(
    corners: &[Vec3; 8],
    p: Vec3,
    start: [f64; 3],
) -> Option<([f64; 3], [Vec3; 3])> {
    locate_or_apart(corners, p, start).ok()
}

/// [`locate_from`]; for a point not in the cell, how far (m) it and the corners may move,
/// together, each along any axis, while it stays out of the cell: its distance outside the
/// cell's box, or beyond the hull of the corners along a direction (their middle's to the
/// point, or a row of the inverse derivative of the cell's map), over how far a move of 1
/// along each axis goes along that direction, less the roundings the tests allow; 0 where not
/// known (Newton's method wandered off, or the cell is degenerate).
pub(crate) fn locate_or_apart(
    corners: &[Vec3; 8],
    p: Vec3,
    start: [f64; 3],
) -> Result<([f64; 3], [Vec3; 3]), f64> {
    // Most points asked about are outside the cell's box (grown by far more than any place
    // Newton's method accepts), and cost 24 comparisons instead of its iterations.
    let (lo, hi) = (corners.iter()).fold((corners[0], corners[0]), |(lo, hi), &c| {
        (lo.min(c), hi.max(c))
    });
    let grow = (hi - lo) * 1e-6;
    let (lo, hi) = (lo - grow, hi + grow);
    if !(p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z) {
        let out = (lo - p).max(p - hi) - grow;
        return Err(out.x.max(out.y).max(out.z).max(0.0));
    }
    // Then beyond every corner along the line from their middle (a point near a turned or
    // sheared cell, inside its box but outside its hull): 8 products instead of Newton's step.
    let rounding = 1e-6 * (hi - lo).length();
    if let Some((beyond, n)) = beyond_hull(corners, p) {
        if beyond > rounding {
            let along = n.x.abs() + n.y.abs() + n.z.abs();
            return Err(((beyond - 2.0 * rounding) / along).max(0.0));
        }
    }
    newton_in(corners, p, 0.0, start)
}

/// How far `p` is beyond the hull of a cell's `corners` (m; negative inside it) along the line
/// from their middle, with that line's unit direction: a cell lies in the hull of its corners,
/// so a point beyond it is outside the cell by at least that much. `None` at the middle.
#[inline]
pub(crate) fn beyond_hull(corners: &[Vec3; 8], p: Vec3) -> Option<(f64, Vec3)> {
    let middle = corners.iter().fold(Vec3::ZERO, |s, &c| s + c) * 0.125;
    let d = p - middle;
    let length = d.length();
    if length <= 0.0 || length.is_nan() {
        return None;
    }
    let n = d / length;
    let beyond = (corners.iter()).fold(f64::INFINITY, |m, &c| m.min(n.dot(p - c)));
    Some((beyond, n))
}

/// [`locate_from`], also for a point outside the cell by up to `slack` of its size along each
/// of `(u, v, w)`: its place then lies outside `[0, 1]³`, where the trilinear map extends.
pub(crate) fn locate_near(
    corners: &[Vec3; 8],
    p: Vec3,
    slack: f64,
    start: [f64; 3],
) -> Option<([f64; 3], [Vec3; 3])> {
    newton_in(corners, p, slack, start).ok()
}

/// [`locate_near`]'s Newton's method; where the point is outside the hull after its first
/// step, how far it is clear of it (see [`locate_or_apart`]), else 0.
fn newton_in(
    corners: &[Vec3; 8],
    p: Vec3,
    slack: f64,
    start: [f64; 3],
) -> Result<([f64; 3], [Vec3; 3]), f64> {
    let cell = Trilinear::new(corners);
    // The cell's size, to judge the residual by.
    let size = (corners[7] - corners[0]).length() + (corners[6] - corners[1]).length();
    let mut uvw = start;
    let mut converged = false;
    for iteration in 0..MAX_LOCATE {
        let r = p - cell.at(uvw);
        if r.length() <= 1e-12 * size {
            converged = true;
            break;
        }
        let inverse = inverse_columns(cell.jacobian(uvw)).ok_or(0.0)?;
        // Δ = J⁻¹ r, with the rows of J⁻¹ as `inverse`.
        let delta = map3(inverse, |row| row.dot(r));
        for (u, d) in uvw.iter_mut().zip(delta) {
            *u += d;
        }
        // The cell lies in the hull of its corners (its points are their weighted means), so
        // a point outside the hull is outside the cell: told, after the first step, along the
        // rows of that step's (affine) inverse, which most points near a cell but not in it
        // are, one step before the test below tells.
        if iteration == 0 && slack == 0.0 {
            if let Some(apart) = outside_hull(corners, &inverse, p) {
                return Err(apart);
            }
        }
        // Far outside the cell: not in it (Newton's method may wander off there). Or outside
        // by far more than the last step, once steps are short: Newton's method converges
        // quadratically, and what is left of the error is about the step squared.
        let step = delta.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let out = if step <= NEAR_STEP { 4.0 * step } else { 1.0 };
        if uvw
            .iter()
            .any(|u| !(-out - slack..=1.0 + out + slack).contains(u))
        {
            return Err(0.0);
        }
    }
    let slack = slack + 1e-9;
    if !converged || uvw.iter().any(|&u| !(-slack..=1.0 + slack).contains(&u)) {
        return Err(0.0);
    }
    let uvw = map3(uvw, |u| u.clamp(-slack, 1.0 + slack));
    // J⁻ᵀ: its columns are the rows of J⁻¹.
    let rows = inverse_columns(cell.jacobian(uvw)).ok_or(0.0)?;
    Ok((uvw, rows))
}

/// Where `p` is outside the hull of `corners` along one of the directions `rows` (beyond every
/// corner by more than a rounding of the corners' spread along it), how far it is clear of it
/// (see [`locate_or_apart`]); `None` inside.
#[inline]
fn outside_hull(corners: &[Vec3; 8], rows: &[Vec3; 3], p: Vec3) -> Option<f64> {
    let mut apart: Option<f64> = None;
    for row in rows {
        let (lo, hi) = corners
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                let x = row.dot(*c);
                (lo.min(x), hi.max(x))
            });
        let x = row.dot(p);
        let rounding = (hi - lo) * 1e-9;
        if !(x >= lo - rounding && x <= hi + rounding) {
            let beyond = (lo - x).max(x - hi) - 2.0 * rounding;
            let along = row.x.abs() + row.y.abs() + row.z.abs();
            let clear = (beyond / along).max(0.0);
            apart = Some(apart.map_or(clear, |a| a.max(clear)));
        }
    }
    apart
}

/// A deformed cell's trilinear map as a polynomial,
/// `x = a + b·u + c·v + d·w + e·uv + f·uw + g·vw + h·uvw`: its point and derivative at a place
/// in fewer operations than by the corners' weights (Newton's method in [`locate`] takes
/// several of each for every point it places).
struct Trilinear {
    a: Vec3,
    b: Vec3,
    c: Vec3,
    d: Vec3,
    e: Vec3,
    f: Vec3,
    g: Vec3,
    h: Vec3,
}

impl Trilinear {
    /// The map of the cell with `corners` in the order of [`CORNERS`] (`4·u + 2·v + w`).
    #[inline]
    fn new(x: &[Vec3; 8]) -> Self {
        let (e, f, g) = (
            x[6] - x[4] - x[2] + x[0],
            x[5] - x[4] - x[1] + x[0],
            x[3] - x[2] - x[1] + x[0],
        );
        Trilinear {
            a: x[0],
            b: x[4] - x[0],
            c: x[2] - x[0],
            d: x[1] - x[0],
            e,
            f,
            g,
            h: x[7] - x[6] - x[5] - x[3] + x[4] + x[2] + x[1] - x[0],
        }
    }

    /// The point at `(u, v, w)`.
    #[inline]
    fn at(&self, [u, v, w]: [f64; 3]) -> Vec3 {
        self.a
            + (self.b + self.e * v) * u
            + (self.c + self.g * w) * v
            + (self.d + (self.f + self.h * v) * u) * w
    }

    /// The derivative at `(u, v, w)`, as columns `∂x/∂u, ∂x/∂v, ∂x/∂w`.
    #[inline]
    fn jacobian(&self, [u, v, w]: [f64; 3]) -> [Vec3; 3] {
        [
            self.b + self.e * v + (self.f + self.h * v) * w,
            self.c + self.e * u + (self.g + self.h * u) * w,
            self.d + self.f * u + (self.g + self.h * u) * v,
        ]
    }
}

/// The point of a deformed cell (its corners in the order of [`CORNERS`]) at its place `uvw`.
#[inline]
pub(crate) fn cell_map(corners: &[Vec3; 8], uvw: [f64; 3]) -> Vec3 {
    corners
        .iter()
        .zip(weights(uvw))
        .fold(Vec3::ZERO, |s, (&c, w)| s + c * w)
}

/// A Newton step of [`locate`] (in the cell's `(u, v, w)`) short enough that what is left of
/// the error is far smaller.
const NEAR_STEP: f64 = 0.05;

/// Newton iterations of [`locate`] at most (a point in a cell is found in four or five).
const MAX_LOCATE: usize = 16;

/// The rows of the inverse of the matrix with columns `c`, or `None` when it is singular.
fn inverse_columns(c: [Vec3; 3]) -> Option<[Vec3; 3]> {
    let (r0, r1, r2) = (c[1].cross(c[2]), c[2].cross(c[0]), c[0].cross(c[1]));
    let det = c[0].dot(r0);
    if !det.is_finite() || det.abs() <= 1e-300 {
        return None;
    }
    Some([r0 / det, r1 / det, r2 / det])
}

/// A gradient over `(u, v, w)` turned into one in space, with `rows` the rows of the cell
/// map's inverse derivative from [`locate`]: `∇ₓφ = J⁻ᵀ ∇ᵤφ`.
#[inline]
pub(crate) fn in_space(g: [f64; 3], rows: &[Vec3; 3]) -> Vec3 {
    rows[0] * g[0] + rows[1] * g[1] + rows[2] * g[2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::body::Material;

    /// A full box's distances are its cage's: 0 on the faces, minus the distance to the
    /// nearest face inside (on the grid [`REFINE`] times as fine), and its samples are the
    /// points of its faces.
    #[test]
    fn a_box_knows_how_deep_each_of_its_points_is() {
        let lattice = Lattice::new([5, 4, 6], Vec3::new(0.8, 0.6, 1.0));
        let body = Body::lattice_box(lattice.clone(), Material::classic());
        let surface = ContactSurface::new(&body);
        let [rx, ry, rz] = surface.refined;
        assert_eq!(surface.refined, [4, 3, 5].map(|n| REFINE * n + 1));
        let h = lattice.spacing() * (1.0 / REFINE as f64);
        let reach = 2.0 * lattice.spacing().length();
        for i in 0..rx {
            for j in 0..ry {
                for k in 0..rz {
                    let x = Vec3::new(i as f64 * h.x, j as f64 * h.y, k as f64 * h.z);
                    let want = -[x.x, 0.8 - x.x, x.y, 0.6 - x.y, x.z, 1.0 - x.z]
                        .into_iter()
                        .fold(f64::INFINITY, f64::min)
                        .min(reach);
                    let got = surface.distance[(i * ry + j) * rz + k];
                    assert!(
                        (got - want).abs() < 1e-12,
                        "({i}, {j}, {k}): {got} against {want}"
                    );
                }
            }
        }
        assert_eq!(surface.samples.len(), 5 * 4 * 6 - 3 * 2 * 4);
    }

    /// The ring of `examples/pile.toml` (`jello shape torus --detail 6 --size 0.4`, 6 cells),
    /// and its skin at rest in its lattice's frame.
    fn small_ring() -> (Body, Vec<Vec3>) {
        let mesh = crate::TriMesh::shape("torus", 6).expect("a torus");
        let vertices: Vec<Vec3> = mesh.vertices.iter().map(|&v| v * 0.4).collect();
        let body = Body::from_mesh(&vertices, &mesh.triangles, 6, 1 << 20, Material::classic())
            .expect("a ring");
        let skin = body.skin.as_ref().expect("a skin");
        let mut rest = vec![Vec3::ZERO; skin.len()];
        skin.positions(&body.lattice().rest_positions(), &mut rest);
        (body, rest)
    }

    /// A ring whose tube is under two cells thick gets the finer grid (the coarser one rounds
    /// its skin by 4 % of a cell, the finer by half that), a box of cells keeps the coarser (its
    /// faces are on the lattice's planes), and the lattice points' distances are the same exact
    /// ones on both grids.
    #[test]
    fn a_tight_curve_gets_a_finer_grid_and_the_lattice_points_keep_their_distances() {
        let (ring, rest) = small_ring();
        let surface = ContactSurface::new(&ring);
        assert_eq!(surface.refine(), FINE_REFINE);
        let lattice = ring.lattice();
        let h = lattice.spacing();
        let probes = skin_probes(
            lattice,
            &rest,
            &ring.skin.as_ref().unwrap().triangles,
            &|_, _, _| true,
        );
        let stray = rounding(
            &probes,
            &surface.distance,
            surface.refined,
            surface.refine,
            h,
        );
        let reach = 2.0 * h.length();
        let triangles = &ring.skin.as_ref().unwrap().triangles;
        let (coarse, at_refine) = signed_distances(
            lattice,
            &surface.cells,
            &rest,
            triangles,
            reach,
            REFINE,
            None,
        );
        // The ring's skin is 24 × 12 flat faces, 30° apart across the tube: the distance kinks
        // at their edges, and the interpolation rounds the kinks by about a quarter of the
        // grid's spacing times that angle, half as much on a grid twice as fine.
        let coarse_stray = rounding(&probes, &at_refine, coarse, REFINE, h);
        assert!(coarse_stray > 4.0 * ROUNDING * h.x, "{coarse_stray} m");
        assert!(stray < 0.6 * coarse_stray, "{stray} m, {coarse_stray} m");
        let [nx, ny, nz] = lattice.counts;
        let [_, fy, fz] = surface.refined;
        let [_, cy, cz] = coarse;
        for (i, j, k) in
            (0..nx).flat_map(|i| (0..ny).flat_map(move |j| (0..nz).map(move |k| (i, j, k))))
        {
            let r = FINE_REFINE;
            let fine = surface.distance[((r * i) * fy + r * j) * fz + r * k];
            let at = at_refine[((REFINE * i) * cy + REFINE * j) * cz + REFINE * k];
            assert_eq!(
                fine.to_bits(),
                at.to_bits(),
                "lattice point ({i}, {j}, {k})"
            );
        }
        let cube = Body::lattice_box(
            Lattice::new([3, 3, 3], Vec3::new(0.2, 0.2, 0.2)),
            Material::classic(),
        );
        assert_eq!(ContactSurface::new(&cube).refine(), REFINE);
    }

    /// The finer grid, made from the coarser one where that puts a point further than a coarse
    /// sub-cell's diagonal from the skin, is the grid made in full near the skin (to the bit),
    /// and within that diagonal, of the same sign, elsewhere.
    #[test]
    fn the_finer_grid_is_exact_near_the_skin() {
        let (ring, rest) = small_ring();
        let surface = ContactSurface::new(&ring);
        let lattice = ring.lattice();
        let triangles = &ring.skin.as_ref().unwrap().triangles;
        let reach = 2.0 * lattice.spacing().length();
        let (_, full) = signed_distances(
            lattice,
            &surface.cells,
            &rest,
            triangles,
            reach,
            FINE_REFINE,
            None,
        );
        let band = (lattice.spacing() * (1.0 / REFINE as f64)).length();
        let mut near = 0;
        for (made, full) in surface.distance.iter().zip(&full) {
            if full.abs() <= band {
                assert!(
                    (made - full).abs() <= band && made * full >= 0.0,
                    "{made} against {full}"
                );
            }
            if made.abs() <= band {
                assert_eq!(made.to_bits(), full.to_bits());
                near += 1;
            } else {
                assert!(
                    (made - full).abs() <= band && made * full > 0.0,
                    "{made} against {full}"
                );
            }
        }
        assert!(near > 1000, "{near} points near the skin");
    }

    /// A body one cell thick still has an inside: the middle of its cell.
    #[test]
    fn a_body_one_cell_thick_has_an_inside() {
        let lattice = Lattice::new([2, 2, 2], Vec3::new(0.2, 0.2, 0.2));
        let body = Body::lattice_box(lattice, Material::classic());
        let surface = ContactSurface::new(&body);
        let (phi, _) = surface.distance_in([0, 0, 0], [0.5, 0.5, 0.5]);
        assert!((phi + 0.1).abs() < 1e-12, "{phi}");
        // Halfway from the bottom face to the middle: half as deep, deeper upward (0.1 m over
        // half the cell: 0.2 m a unit of w).
        let (phi, g) = surface.distance_in([0, 0, 0], [0.5, 0.5, 0.25]);
        assert!((phi + 0.05).abs() < 1e-12, "{phi}");
        assert!((g[2] + 0.2).abs() < 1e-12, "{g:?}");
    }

    /// Newton's method finds a point's place in a sheared, stretched cell, and a function
    /// linear in space comes back with its gradient.
    #[test]
    fn a_point_is_located_in_a_deformed_cell() {
        let corners = CORNERS.map(|[a, b, c]| {
            let (a, b, c) = (a as f64, b as f64, c as f64);
            Vec3::new(
                0.3 + 0.5 * a + 0.1 * b,
                0.4 * b + 0.05 * a * c,
                0.6 * c + 0.02 * a * b,
            )
        });
        let uvw = [0.3, 0.7, 0.45];
        let w = weights(uvw);
        let p = corners
            .iter()
            .zip(w)
            .fold(Vec3::ZERO, |s, (&c, w)| s + c * w);
        let (found, rows) = locate(&corners, p).expect("inside");
        for (f, u) in found.iter().zip(uvw) {
            assert!((f - u).abs() < 1e-12, "{found:?}");
        }
        // φ(x) = x·a composed with the trilinear map is trilinear in (u, v, w): its gradient
        // over (u, v, w), turned into space, is a.
        let a = Vec3::new(1.0, -2.0, 0.5);
        let d = corners.map(|c| c.dot(a));
        let mut gu = [0.0; 3];
        for (d, dw) in d.iter().zip(weight_derivatives(found)) {
            for (g, dw) in gu.iter_mut().zip(dw) {
                *g += d * dw;
            }
        }
        let g = in_space(gu, &rows);
        assert!((g - a).max_abs() < 1e-9, "{g:?}");
        assert!(locate(&corners, Vec3::new(5.0, 0.0, 0.0)).is_none());
    }

    /// The cell map as a polynomial is the corners' weighted mean, its derivative that of the
    /// weights, and every point of the cell is in its corners' hull along any directions, on
    /// cells twisted and stretched at random; points a little outside a cell, but in its box,
    /// are not placed in it.
    #[test]
    fn the_polynomial_map_and_the_hull_agree_with_the_corners() {
        let mut x = 7u64;
        let mut next = move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        for _ in 0..200 {
            let corners = CORNERS.map(|[a, b, c]| {
                Vec3::new(a as f64, b as f64, c as f64) * 0.1
                    + Vec3::new(next(), next(), next()) * 0.02
            });
            let cell = Trilinear::new(&corners);
            let rows = [0; 3].map(|_| Vec3::new(next(), next(), next()));
            for _ in 0..20 {
                let uvw = [0; 3].map(|_| 0.5 + 0.5 * next());
                let p = cell_map(&corners, uvw);
                assert!((cell.at(uvw) - p).max_abs() < 1e-15);
                let mut j = [Vec3::ZERO; 3];
                for (c, d) in corners.iter().zip(weight_derivatives(uvw)) {
                    for (col, dk) in j.iter_mut().zip(d) {
                        *col += *c * dk;
                    }
                }
                for (a, b) in cell.jacobian(uvw).iter().zip(j) {
                    assert!((*a - b).max_abs() < 1e-15);
                }
                assert!(outside_hull(&corners, &rows, p).is_none());
                let (found, _) = locate(&corners, p).expect("a point of the cell");
                assert!(found.iter().zip(uvw).all(|(f, u)| (f - u).abs() < 1e-9));
                // Out through a face, by a tenth of the cell.
                let mut out = uvw;
                out[0] = -0.1;
                assert!(locate(&corners, cell_map(&corners, out)).is_none());
            }
        }
    }
}
