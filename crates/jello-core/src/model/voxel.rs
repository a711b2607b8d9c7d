//! Voxelising a closed triangle mesh: the cells of a regular grid that its solid occupies.
//!
//! The grid has cubic cells of side `h = L / N`, `L` the longest side of the mesh's bounding box
//! and `N` the cells asked for along it; it starts at the bounding box's lower corner, so the
//! mesh's extreme faces lie on the grid's outer planes. The rule:
//!
//! **A cell is kept when the solid reaches inside it**: when a triangle of the surface passes
//! through the cell's interior, or when the cell's centre lies inside the solid. Then every cell
//! that holds any of the solid's volume is kept, and so is every cell holding a mesh vertex
//! (the skin's anchors, see [`crate::model::skin`]), so that the cage of kept cells encloses the whole
//! mesh. A surface that only touches a cell along its boundary (a face lying on a grid plane)
//! does not keep it. Holes through the solid (a torus) stay open where they are at least a cell
//! wide; parts thinner than a cell keep the cells they pass through.
//!
//! **On a plane means within [`ON_PLANE`] of it.** A face or a vertex lying on a plane between
//! cells must not depend on how its coordinates round: `0.2` and the plane `0.6 / 3 =
//! 0.19999999999999998` are the same place, and so are a binary STL's 32-bit `0.2f32` and the
//! 64-bit `0.2` of an OBJ. So a face that enters a cell by less than `ON_PLANE` cell sides does not
//! enter it; a side within `ON_PLANE` cells of a whole number of cells gets that number; and a
//! vertex within `ON_PLANE` cells of a plane belongs to whichever cell beside it the solid keeps,
//! keeping a cell of its own only when none of them is kept. The same solid then keeps the same
//! cells whatever the file format and its rounding.
//!
//! "Inside" is decided per row of cell centres by a ray along +x, counting the surface's
//! crossings with their orientation (the winding number). Each projected edge's side is computed
//! once, in one canonical order of its two vertices, and a ray through an edge or a vertex goes
//! to exactly one of the triangles there (the top-left rule of rasterisers), so a ray that grazes
//! an edge is neither lost nor counted twice.

use crate::model::error::ModelError;
use crate::vec3::Vec3;

/// How close to a plane between cells, in cell sides, a face or a vertex counts as lying on it
/// (see the module documentation). Far above the rounding of 64-bit coordinates (1e-16 of
/// them) and of binary STL's 32-bit ones (6e-8 of them: within 1e-5 of a cell for a mesh up to
/// about 150 cells from the origin), and far below anything a cell's content could notice.
pub const ON_PLANE: f64 = 1e-5;

/// The cells of a regular grid that a solid occupies.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxels {
    /// Lower corner of the grid (m): the mesh's bounding-box minimum.
    pub origin: Vec3,
    /// Side of every (cubic) cell (m).
    pub cell: f64,
    /// Cells along x, y and z (each ≥ 1).
    pub cells: [usize; 3],
    /// Per cell, whether it is kept; flat index `(i·cy + j)·cz + k`.
    pub occupied: Vec<bool>,
}

impl Voxels {
    /// Voxelises the closed, outward-wound surface `vertices` / `triangles` with `cells` cells
    /// along the longest side of its bounding box.
    ///
    /// Fails when `cells` is 0, when there is nothing to voxelise, when an index is out of
    /// range, or when the grid would have more than `max_cells` cells in all.
    pub fn from_mesh(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        cells: usize,
        max_cells: usize,
    ) -> Result<Voxels, ModelError> {
        if cells == 0 {
            return Err(ModelError::new("--cells must be at least 1"));
        }
        if triangles.is_empty() {
            return Err(ModelError::new("the mesh has no triangles"));
        }
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&v| v as usize >= vertices.len()))
        {
            return Err(ModelError::new(format!(
                "triangle {t:?} refers to a vertex that does not exist ({} vertices)",
                vertices.len()
            )));
        }
        if let Some(n) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::new(format!(
                "mesh coordinates must be finite (vertex {} is {})",
                n + 1,
                vertices[n]
            )));
        }
        let mut used = vec![false; vertices.len()];
        triangles
            .iter()
            .flatten()
            .for_each(|&v| used[v as usize] = true);
        if let Some(n) = used.iter().position(|&u| !u) {
            return Err(ModelError::new(format!(
                "vertex {} is used by no triangle (the skin ties every vertex to the cage)",
                n + 1
            )));
        }
        let (lo, hi) = bounds(vertices, triangles);
        let size = hi - lo;
        let longest = size.x.max(size.y).max(size.z);
        if longest <= 0.0 {
            return Err(ModelError::new("the mesh has no extent"));
        }
        let h = longest / cells as f64;
        // Cells per axis: enough to cover the side (the longest gets exactly `cells`).
        let count = |side: f64| {
            if side == longest {
                cells
            } else {
                // A side within ON_PLANE of a whole number of cells gets that number.
                (side / h - ON_PLANE).ceil().max(1.0) as usize
            }
        };
        let counts = [count(size.x), count(size.y), count(size.z)];
        let total = counts
            .iter()
            .try_fold(1usize, |a, &c| a.checked_mul(c))
            .filter(|&n| n <= max_cells)
            .ok_or_else(|| {
                ModelError::new(format!(
                    "{}×{}×{} cells is more than the {max_cells} allowed",
                    counts[0], counts[1], counts[2]
                ))
            })?;
        let mut voxels = Voxels {
            origin: lo,
            cell: h,
            cells: counts,
            occupied: vec![false; total],
        };
        voxels.mark_surface_cells(vertices, triangles);
        voxels.mark_inside_cells(vertices, triangles);
        // Every vertex in a kept cell (the skin's anchors): one the solid keeps when the vertex
        // lies on a plane between cells, else its own.
        for &v in vertices {
            let c = voxels.anchor_cell(v);
            let index = voxels.index(c);
            voxels.occupied[index] = true;
        }
        Ok(voxels)
    }

    /// Flat index of cell `(i, j, k)`.
    #[inline]
    pub fn index(&self, [i, j, k]: [usize; 3]) -> usize {
        (i * self.cells[1] + j) * self.cells[2] + k
    }

    /// The cell holding point `p`, clamped into the grid (a point on a plane between two cells
    /// belongs to the upper one, except on the grid's upper boundary).
    pub fn cell_of(&self, p: Vec3) -> [usize; 3] {
        let local = (p - self.origin) / self.cell;
        let axis = |c: f64, n: usize| (c.floor().max(0.0) as usize).min(n - 1);
        [
            axis(local.x, self.cells[0]),
            axis(local.y, self.cells[1]),
            axis(local.z, self.cells[2]),
        ]
    }

    /// The cell that carries vertex `p`: when `p` lies on a plane between cells (within
    /// [`ON_PLANE`] cell sides), the first kept one of the cells beside it, its own
    /// ([`Voxels::cell_of`]) first; otherwise, or when none is kept, its own.
    pub fn anchor_cell(&self, p: Vec3) -> [usize; 3] {
        let own = self.cell_of(p);
        let local = ((p - self.origin) / self.cell).to_array();
        // Per axis, the cells to try: its own, and the one across an inner plane it lies on.
        let choices: [[usize; 2]; 3] = std::array::from_fn(|a| {
            let plane = local[a].round();
            let inner = plane >= 1.0 && plane <= (self.cells[a] - 1) as f64;
            if inner && (local[a] - plane).abs() <= ON_PLANE {
                let above = plane as usize;
                let other = if own[a] == above { above - 1 } else { above };
                [own[a], other]
            } else {
                [own[a]; 2]
            }
        });
        for i in choices[0] {
            for j in choices[1] {
                for k in choices[2] {
                    if self.occupied[self.index([i, j, k])] {
                        return [i, j, k];
                    }
                }
            }
        }
        own
    }

    /// Number of kept cells.
    pub fn occupied_count(&self) -> usize {
        self.occupied.iter().filter(|&&o| o).count()
    }

    /// Volume of the kept cells (m³).
    pub fn volume(&self) -> f64 {
        self.occupied_count() as f64 * self.cell.powi(3)
    }

    /// Lower corner of cell `(i, j, k)` (m).
    pub fn cell_min(&self, [i, j, k]: [usize; 3]) -> Vec3 {
        self.origin + Vec3::new(i as f64, j as f64, k as f64) * self.cell
    }

    /// Keeps the cells whose interior a triangle passes through.
    fn mark_surface_cells(&mut self, vertices: &[Vec3], triangles: &[[u32; 3]]) {
        let h = self.cell;
        // A cell shrunk by this much on every side: a triangle that only touches the cell's
        // boundary (within ON_PLANE) does not count.
        let inset = h * ON_PLANE;
        let half = Vec3::new(h, h, h) * 0.5 - Vec3::new(inset, inset, inset);
        for t in triangles {
            let tri = t.map(|v| vertices[v as usize]);
            let lo = tri[0].min(tri[1]).min(tri[2]);
            let hi = tri[0].max(tri[1]).max(tri[2]);
            let [i0, j0, k0] = self.cell_of(lo);
            let [i1, j1, k1] = self.cell_of(hi);
            for i in i0..=i1 {
                for j in j0..=j1 {
                    for k in k0..=k1 {
                        let index = self.index([i, j, k]);
                        if self.occupied[index] {
                            continue;
                        }
                        let centre = self.cell_min([i, j, k]) + Vec3::new(h, h, h) * 0.5;
                        if triangle_meets_box(tri, centre, half) {
                            self.occupied[index] = true;
                        }
                    }
                }
            }
        }
    }

    /// Keeps the cells whose centre lies inside the solid: one ray along +x per row of centres.
    fn mark_inside_cells(&mut self, vertices: &[Vec3], triangles: &[[u32; 3]]) {
        let [nx, ny, nz] = self.cells;
        let h = self.cell;
        // Triangles by the rows of centres their projection on the yz-plane may cover.
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); ny * nz];
        let row_range = |lo: f64, hi: f64, origin: f64, n: usize| {
            // Centres at origin + (c + ½)·h within [lo, hi].
            let first = ((lo - origin) / h - 0.5).ceil().max(0.0) as usize;
            let last = ((hi - origin) / h - 0.5).floor();
            if last < 0.0 {
                return 0..0;
            }
            first..(last as usize + 1).min(n)
        };
        for (n, t) in triangles.iter().enumerate() {
            let tri = t.map(|v| vertices[v as usize]);
            let lo = tri[0].min(tri[1]).min(tri[2]);
            let hi = tri[0].max(tri[1]).max(tri[2]);
            for j in row_range(lo.y, hi.y, self.origin.y, ny) {
                for k in row_range(lo.z, hi.z, self.origin.z, nz) {
                    rows[j * nz + k].push(n as u32);
                }
            }
        }
        let mut crossings: Vec<(f64, i32)> = Vec::new();
        for j in 0..ny {
            for k in 0..nz {
                let y = self.origin.y + (j as f64 + 0.5) * h;
                let z = self.origin.z + (k as f64 + 0.5) * h;
                crossings.clear();
                for &n in &rows[j * nz + k] {
                    let t = triangles[n as usize];
                    if let Some(crossing) = ray_crossing(vertices, t, y, z) {
                        crossings.push(crossing);
                    }
                }
                crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
                // Sweep the centres of the row, adding each crossing's orientation once the
                // centre is past it: a non-zero sum is inside.
                let mut winding = 0;
                let mut next = 0;
                for i in 0..nx {
                    let x = self.origin.x + (i as f64 + 0.5) * h;
                    while next < crossings.len() && crossings[next].0 < x {
                        winding += crossings[next].1;
                        next += 1;
                    }
                    if winding != 0 {
                        let index = self.index([i, j, k]);
                        self.occupied[index] = true;
                    }
                }
            }
        }
    }
}

/// Smallest and largest coordinates of the vertices the triangles use (all finite).
fn bounds(vertices: &[Vec3], triangles: &[[u32; 3]]) -> (Vec3, Vec3) {
    let inf = f64::INFINITY;
    let mut lo = Vec3::new(inf, inf, inf);
    let mut hi = -lo;
    for t in triangles {
        for &v in t {
            let p = vertices[v as usize];
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    (lo, hi)
}

/// Where the ray `{(x, y, z) : x ∈ ℝ}` crosses triangle `t`, and the crossing's orientation
/// (+1 where the ray enters the solid, the outward normal pointing against +x; −1 where it
/// leaves); `None` when it misses or the triangle is edge-on.
///
/// The projected edge functions are computed with each edge's vertices in a canonical order
/// (lower index first) and negated for the other direction, so two triangles sharing an edge
/// see exactly opposite values; a ray exactly on an edge or a vertex is given to one triangle
/// by the top-left rule.
pub(crate) fn ray_crossing(vertices: &[Vec3], t: [u32; 3], y: f64, z: f64) -> Option<(f64, i32)> {
    let p = t.map(|v| vertices[v as usize]);
    // Edge function of the directed edge a → b at (y, z): positive on the left of it in the
    // (y, z) plane. Computed with the lower vertex index first and negated for the other
    // direction, so two triangles sharing the edge get exactly opposite values.
    let edge = |a: u32, b: u32| -> f64 {
        let (lo, hi, flip) = if a < b { (a, b, 1.0) } else { (b, a, -1.0) };
        let (u, w) = (vertices[lo as usize], vertices[hi as usize]);
        flip * ((w.y - u.y) * (z - u.z) - (w.z - u.z) * (y - u.y))
    };
    // The weight of vertex e is the edge opposite it.
    let e = [edge(t[1], t[2]), edge(t[2], t[0]), edge(t[0], t[1])];
    let positive = e.iter().any(|&w| w > 0.0);
    let negative = e.iter().any(|&w| w < 0.0);
    // Mixed signs: outside. All zero: edge-on (or degenerate), no crossing.
    if positive == negative {
        return None;
    }
    // The projected orientation, read off the same three values (watertight: no separately
    // rounded area can disagree with them).
    let sign = if positive { 1.0 } else { -1.0 };
    for (k, &w) in e.iter().enumerate() {
        if w == 0.0 {
            // On the edge opposite vertex k: the triangle owns the ray only if that edge is a
            // "top-left" one (its direction, in the triangle's orientation, points to −z, or
            // along +y when horizontal): of the two triangles sharing it, exactly one.
            let (u, v) = (p[(k + 1) % 3], p[(k + 2) % 3]);
            let (dy, dz) = ((v.y - u.y) * sign, (v.z - u.z) * sign);
            if !(dz < 0.0 || (dz == 0.0 && dy > 0.0)) {
                return None;
            }
        }
    }
    let weights = e.map(|w| w * sign);
    let total = weights[0] + weights[1] + weights[2];
    let x = (weights[0] * p[0].x + weights[1] * p[1].x + weights[2] * p[2].x) / total;
    // Entering the solid (outward normal against +x: negative orientation) counts +1.
    Some((x, if positive { -1 } else { 1 }))
}

/// Whether triangle `tri` meets the box of half-sides `half` about `centre` (separating axis
/// test: the box's 3 axes, the triangle's normal, and the 9 cross products of their edges;
/// touching counts as meeting).
fn triangle_meets_box(tri: [Vec3; 3], centre: Vec3, half: Vec3) -> bool {
    let v = tri.map(|p| p - centre);
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let h = half.to_array();
    let separated_on = |axis: Vec3| {
        let r = h[0] * axis.x.abs() + h[1] * axis.y.abs() + h[2] * axis.z.abs();
        let d = [axis.dot(v[0]), axis.dot(v[1]), axis.dot(v[2])];
        let (lo, hi) = (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]));
        lo > r || hi < -r
    };
    let units = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    if units.iter().any(|&u| separated_on(u)) {
        return false;
    }
    if separated_on(e[0].cross(e[1])) {
        return false;
    }
    for u in units {
        for edge in e {
            if separated_on(u.cross(edge)) {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rays through the vertices and along the edges of an octahedron's projection: the
    /// winding number is still exactly 1 inside and 0 outside (no crossing lost or doubled).
    /// A vertex that is not a number is named with its place, as a user writes one.
    #[test]
    fn a_vertex_not_a_number_is_shown_as_written() {
        let vertices = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, f64::NAN, 0.5),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let triangles = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let error = Voxels::from_mesh(&vertices, &triangles, 2, 1000).unwrap_err();
        assert!(
            error.to_string().contains("vertex 3 is (0, NaN, 0.5)"),
            "{error}"
        );
    }

    #[test]
    fn rays_through_edges_and_vertices_count_once() {
        let vertices = vec![
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ];
        // Outward: each face (±x, ±y, ±z) counter-clockwise seen from outside.
        let mut triangles = Vec::new();
        for (x, sx) in [(0u32, 1.0), (1, -1.0)] {
            for (y, sy) in [(2u32, 1.0), (3, -1.0)] {
                for (z, sz) in [(4u32, 1.0), (5, -1.0)] {
                    let outward = sx * sy * sz > 0.0;
                    triangles.push(if outward { [x, y, z] } else { [x, z, y] });
                }
            }
        }
        for (y, z) in [
            (0.0, 0.0), // through two vertices
            (0.0, 0.5), // along edges
            (0.5, 0.0),
            (-0.25, 0.0),
            (0.5, 0.5),   // on the silhouette
            (0.25, -0.5), // plain
            (1.0, 0.0),   // through the silhouette's vertex
        ] {
            let mut crossings: Vec<(f64, i32)> = triangles
                .iter()
                .filter_map(|&t| ray_crossing(&vertices, t, y, z))
                .collect();
            crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
            for i in 0..=40 {
                let x = -1.25 + i as f64 / 16.0;
                let inside = x.abs() + f64::abs(y) + f64::abs(z) < 1.0;
                let on_surface = x.abs() + f64::abs(y) + f64::abs(z) == 1.0;
                if on_surface {
                    continue;
                }
                let winding: i32 = crossings.iter().filter(|c| c.0 < x).map(|c| c.1).sum();
                assert_eq!(
                    winding != 0,
                    inside,
                    "ray (y, z) = ({y}, {z}) at x = {x}: winding {winding}, crossings {crossings:?}"
                );
                assert!(winding == 0 || winding == 1, "winding {winding}");
            }
        }
    }
}
