//! [`Surface`]: what is drawn and exported of a model, as one triangle mesh over all bodies.
//! A body carrying a skin shows its skin (vertices at the trilinear interpolation of their cells'
//! corners); a body without one shows the surface of its cage of cells.

use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

/// One mesh over all bodies: per body a skin or a cage, one after the other.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    parts: Vec<Part>,
    triangles: Vec<[u32; 3]>,
    vertices: usize,
}

#[derive(Clone, Debug, PartialEq)]
enum Part {
    /// Body `body`'s skin.
    Skin { body: usize },
    /// Lattice points (flat indices of the model) of a cage, in vertex order.
    Cage { points: Vec<usize> },
}

/// Which cage points a [`Surface`] has as vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CageVertices {
    /// Every lattice point of the body, in flat-index order (the classic frame files).
    All,
    /// Only the points its surface triangles use.
    Used,
}

impl Surface {
    /// The surface of `model`'s bodies.
    pub fn new(model: &Model, cage: CageVertices) -> Self {
        let mut parts = Vec::new();
        let mut triangles = Vec::new();
        let mut vertices = 0u32;
        for (b, body) in model.bodies().iter().enumerate() {
            if let Some(skin) = &body.skin {
                triangles.extend(skin.triangles.iter().map(|t| t.map(|v| v + vertices)));
                vertices += skin.len() as u32;
                parts.push(Part::Skin { body: b });
                continue;
            }
            let first = body.points().start;
            let cage_triangles = body.surface_triangles();
            let points: Vec<usize> = match cage {
                CageVertices::All => body.points().collect(),
                CageVertices::Used => {
                    let mut used = vec![false; body.len()];
                    cage_triangles
                        .iter()
                        .flatten()
                        .for_each(|&p| used[p as usize] = true);
                    (0..body.len())
                        .filter(|&p| used[p])
                        .map(|p| first + p)
                        .collect()
                }
            };
            let mut vertex_of = vec![u32::MAX; body.len()];
            for (v, &p) in points.iter().enumerate() {
                vertex_of[p - first] = vertices + v as u32;
            }
            triangles.extend(
                cage_triangles
                    .iter()
                    .map(|t| t.map(|p| vertex_of[p as usize])),
            );
            vertices += points.len() as u32;
            parts.push(Part::Cage { points });
        }
        Surface {
            parts,
            triangles,
            vertices: vertices as usize,
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices
    }

    /// The triangles, wound outward, as vertex indices.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Per body, in order, the range of vertices that draw it.
    pub fn body_vertices(&self, model: &Model) -> Vec<std::ops::Range<usize>> {
        let mut start = 0;
        self.parts
            .iter()
            .map(|part| {
                let len = match part {
                    Part::Skin { body } => model.body(*body).skin.as_ref().map_or(0, |s| s.len()),
                    Part::Cage { points } => points.len(),
                };
                start += len;
                start - len..start
            })
            .collect()
    }

    /// The model's point (flat index) that carries vertex `v` most: for a skin, the corner of
    /// the vertex's cell with the largest weight; for a cage, the vertex's own point. What
    /// pulling the drawn surface at `v` pulls. Panics when `v` is out of range.
    pub fn vertex_point(&self, model: &Model, v: usize) -> usize {
        let mut start = 0;
        for part in &self.parts {
            match part {
                Part::Skin { body } => {
                    let body = model.body(*body);
                    let skin = body.skin.as_ref().expect("a skin part has a skin");
                    if v < start + skin.len() {
                        return body.points().start + skin.nearest_corner(v - start);
                    }
                    start += skin.len();
                }
                Part::Cage { points } => {
                    if v < start + points.len() {
                        return points[v - start];
                    }
                    start += points.len();
                }
            }
        }
        panic!(
            "vertex {v} is past the surface's {} vertices",
            self.vertices
        )
    }

    /// The vertices' positions in `state`, written to `out` (resized to the vertex count).
    pub fn positions(&self, model: &Model, state: &State, out: &mut Vec<Vec3>) {
        out.clear();
        for part in &self.parts {
            match part {
                Part::Skin { body } => {
                    let body = model.body(*body);
                    let skin = body.skin.as_ref().expect("a skin part has a skin");
                    let start = out.len();
                    out.resize(start + skin.len(), Vec3::ZERO);
                    skin.positions(&state.pos[body.points()], &mut out[start..]);
                }
                Part::Cage { points } => out.extend(points.iter().map(|&p| state.pos[p])),
            }
        }
    }
}
