//! The skin: a triangle mesh whose vertices follow a lattice of voxel cells.
//!
//! Every vertex is embedded at rest in one cell of the [`Voxels`] grid by its place in the cell,
//! `(u, v, w) ∈ [0, 1]³`, and afterwards sits at the trilinear interpolation of the cell's eight
//! corners: `Σ (1−u or u)(1−v or v)(1−w or w) · corner`. At rest that is the vertex itself (up to
//! rounding, far below 1e-12 m for metre-sized meshes). The skin is what is drawn and exported;
//! the lattice is the cage that moves it (Vega's CubicMesh and Rapier's soft bodies embed a mesh
//! the same way).
//!
//! The lattice of a voxel grid has a point at every cell corner: `cells + 1` points per axis,
//! flat index `(i·ny + j)·nz + k` as every lattice in Jello.

use crate::model::lattice::Lattice;
use crate::model::voxel::Voxels;
use crate::vec3::Vec3;

/// A mesh embedded in the cells of a voxel lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    /// Per vertex: lattice index of the lower corner `(i, j, k)` of its cell.
    pub corner: Vec<u32>,
    /// Per vertex: its place in the cell, each coordinate in `[0, 1]` (up to
    /// [`crate::model::voxel::ON_PLANE`] outside it for a vertex on a plane between cells that
    /// the cell beside it carries).
    pub local: Vec<[f64; 3]>,
    /// Triangles, as indices into the vertices (the input mesh's).
    pub triangles: Vec<[u32; 3]>,
    /// Lattice points per axis (`cells + 1`).
    counts: [usize; 3],
}

impl Voxels {
    /// The lattice of the grid's cell corners: `cells + 1` points per axis, spacing `cell`. Its
    /// rest positions are relative to [`Voxels::origin`].
    pub fn lattice(&self) -> Lattice {
        let [cx, cy, cz] = self.cells;
        Lattice::new(
            [cx + 1, cy + 1, cz + 1],
            Vec3::new(cx as f64, cy as f64, cz as f64) * self.cell,
        )
    }

    /// Per lattice point, whether it is a corner of a kept cell.
    pub fn active_points(&self) -> Vec<bool> {
        crate::model::body::corners_of_kept(&self.lattice(), &self.occupied)
    }

    /// Rest positions of the lattice points (m), in the mesh's own frame.
    pub fn rest_points(&self) -> Vec<Vec3> {
        self.lattice()
            .rest_positions()
            .into_iter()
            .map(|p| self.origin + p)
            .collect()
    }
}

/// The eight corners of a cell, as offsets; index `a·4 + b·2 + c`.
const CORNERS: [(usize, usize, usize); 8] = [
    (0, 0, 0),
    (0, 0, 1),
    (0, 1, 0),
    (0, 1, 1),
    (1, 0, 0),
    (1, 0, 1),
    (1, 1, 0),
    (1, 1, 1),
];

impl Skin {
    /// Embeds the mesh `vertices` / `triangles` in the cells of `voxels` (made from the same
    /// mesh, so that every vertex's [`Voxels::anchor_cell`] is kept).
    pub fn embed(voxels: &Voxels, vertices: &[Vec3], triangles: &[[u32; 3]]) -> Skin {
        let lattice = voxels.lattice();
        let (corner, local) = vertices
            .iter()
            .map(|&p| {
                let [i, j, k] = voxels.anchor_cell(p);
                debug_assert!(voxels.occupied[voxels.index([i, j, k])]);
                let base = voxels.cell_min([i, j, k]);
                // Not clamped: a vertex on a plane between cells may be a rounding error
                // outside the cell that carries it, and the interpolation puts it back exactly.
                let uvw = ((p - base) / voxels.cell).to_array();
                (lattice.index(i, j, k) as u32, uvw)
            })
            .unzip();
        Skin {
            corner,
            local,
            triangles: triangles.to_vec(),
            counts: lattice.counts,
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.corner.len()
    }

    /// True when the skin has no vertices.
    pub fn is_empty(&self) -> bool {
        self.corner.is_empty()
    }

    /// The vertices' positions for lattice points at `points` (flat lattice index), written to
    /// `out` (one per vertex): each the trilinear interpolation of its cell's corners.
    pub fn positions(&self, points: &[Vec3], out: &mut [Vec3]) {
        let [_, ny, nz] = self.counts;
        let offsets = CORNERS.map(|(a, b, c)| (a * ny + b) * nz + c);
        for ((out, &corner), &[u, v, w]) in out.iter_mut().zip(&self.corner).zip(&self.local) {
            let base = corner as usize;
            let weight = |(a, b, c): (usize, usize, usize)| {
                let f = |s: usize, t: f64| if s == 1 { t } else { 1.0 - t };
                f(a, u) * f(b, v) * f(c, w)
            };
            let mut p = Vec3::ZERO;
            for (&(a, b, c), &offset) in CORNERS.iter().zip(&offsets) {
                p += points[base + offset] * weight((a, b, c));
            }
            *out = p;
        }
    }

    /// The lattice point (flat index) that carries vertex `v` most: the corner of its cell with
    /// the largest trilinear weight. What a pull on the skin pulls.
    pub fn nearest_corner(&self, v: usize) -> usize {
        let [_, ny, nz] = self.counts;
        let [a, b, c] = self.local[v].map(|t| usize::from(t > 0.5));
        self.corner[v] as usize + (a * ny + b) * nz + c
    }

    /// Smooth vertex normals of the skin at vertex positions `positions`, written to `out`
    /// (see [`vertex_normals`]).
    pub fn normals(&self, positions: &[Vec3], out: &mut [Vec3]) {
        vertex_normals(positions, &self.triangles, out);
    }
}

/// The volume (m³) the closed, outward-wound triangle mesh `positions` / `triangles` encloses,
/// by the divergence theorem: the signed volumes of the tetrahedra joining each triangle to the
/// middle of the mesh's bounding box (not the origin, so that a mesh far from it loses no
/// precision), summed. Negative for an inward-wound mesh; 0 for no triangles.
pub fn enclosed_volume(positions: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    let Some(&first) = positions.first() else {
        return 0.0;
    };
    let (lo, hi) = positions
        .iter()
        .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let centre = lo * 0.5 + hi * 0.5;
    let six: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize] - centre);
            a.dot(b.cross(c))
        })
        .sum();
    six / 6.0
}

/// Smooth unit vertex normals of the triangle mesh `positions` / `triangles` into `out` (one per
/// position): the sum of the normals of the triangles around each vertex, weighted by their
/// areas, normalised; a vertex whose triangles all have zero area gets +z.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut [Vec3]) {
    out.fill(Vec3::ZERO);
    for t in triangles {
        let [a, b, c] = t.map(|v| v as usize);
        // Twice the area times the unit normal.
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        out[a] += n;
        out[b] += n;
        out[c] += n;
    }
    for n in out.iter_mut() {
        let l = n.length();
        *n = if l > 0.0 {
            *n / l
        } else {
            Vec3::new(0.0, 0.0, 1.0)
        };
    }
}
