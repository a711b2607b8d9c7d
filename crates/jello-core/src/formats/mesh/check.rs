//! The checks every reader's mesh must pass (see the module docs of [`crate::formats::mesh`]): at least
//! one triangle, none degenerate, closed, manifold and consistently oriented, a finite non-zero
//! volume; then unused vertices dropped and an inside-out mesh flipped.

use super::{MeshError, TriMesh};
use crate::formats::world::Num;
use crate::vec3::Vec3;

/// Which reader made a [`Raw`] mesh: how its triangles and vertices are named in messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    /// Faces have lines; vertices are the file's, counted from 1.
    Obj,
    /// Facets have lines; vertices are welded, counted from 0.
    StlAscii,
    /// Triangles are counted from 1; vertices are welded, counted from 0.
    StlBinary,
}

/// A mesh as read, before its checks.
pub(super) struct Raw<'a> {
    /// The source name, for errors.
    pub(super) name: &'a str,
    /// Which reader: how to name things in errors.
    pub(super) format: Format,
    /// Vertex positions, all finite.
    pub(super) vertices: Vec<Vec3>,
    /// Triangles, indices in range.
    pub(super) triangles: Vec<[u32; 3]>,
    /// The line each triangle comes from (empty for binary STL).
    pub(super) lines: Vec<usize>,
}

/// What is wrong at an edge: the half-edges involved are `half[start..start + len]`.
#[derive(Clone, Copy)]
enum Problem {
    /// Used by one triangle.
    Open,
    /// Used twice in the same direction.
    Flipped,
    /// Used by two triangles with the same three vertices, facing opposite ways.
    Sheet,
    /// Used three or more times.
    NonManifold,
}

/// Positions in messages: `(x, y, z)`, each number in the world file's shortest round-trip form
/// (scientific notation when very large or small).
pub(super) fn at(p: Vec3) -> String {
    format!("({}, {}, {})", Num(p.x), Num(p.y), Num(p.z))
}

impl<'a> Raw<'a> {
    /// An empty mesh for the reader `format` of the file `name`.
    pub(super) fn new(name: &'a str, format: Format) -> Self {
        Raw {
            name,
            format,
            vertices: Vec::new(),
            triangles: Vec::new(),
            lines: Vec::new(),
        }
    }

    /// Adds a vertex; an error (at `line`) when there would be more than `u32` can index.
    pub(super) fn push_vertex(&mut self, p: Vec3, line: usize) -> Result<u32, MeshError> {
        let i = u32::try_from(self.vertices.len())
            .ok()
            .filter(|&i| i < u32::MAX)
            .ok_or_else(|| {
                MeshError::new(
                    self.name,
                    line,
                    format!("too many vertices: at most {} are supported", u32::MAX),
                )
            })?;
        self.vertices.push(p);
        Ok(i)
    }

    /// Adds a triangle read from `line` (ignored for binary STL).
    pub(super) fn push_triangle(&mut self, t: [u32; 3], line: usize) {
        self.triangles.push(t);
        if self.format != Format::StlBinary {
            self.lines.push(line);
        }
    }

    /// The line triangle `t` comes from; 0 for binary STL.
    fn line(&self, t: usize) -> usize {
        self.lines.get(t).copied().unwrap_or(0)
    }

    /// Triangle `t` as a message names it.
    fn place(&self, t: usize) -> String {
        match self.format {
            Format::Obj => format!("the face on line {}", self.line(t)),
            Format::StlAscii => format!("the facet on line {}", self.line(t)),
            Format::StlBinary => format!("triangle {}", t + 1),
        }
    }

    /// Triangles `ts` (ascending) as a message names them: at most four, each line once.
    fn places(&self, ts: &[usize]) -> String {
        let mut named: Vec<usize> = match self.format {
            Format::StlBinary => ts.iter().map(|t| t + 1).collect(),
            _ => ts.iter().map(|&t| self.line(t)).collect(),
        };
        named.dedup();
        let (noun, nouns) = match self.format {
            Format::Obj => ("the face on line", "the faces on lines"),
            Format::StlAscii => ("the facet on line", "the facets on lines"),
            Format::StlBinary => ("triangle", "triangles"),
        };
        const MAX: usize = 4;
        let shown: Vec<String> = named.iter().take(MAX).map(|n| n.to_string()).collect();
        match named.len() {
            1 => format!("{noun} {}", shown[0]),
            n if n <= MAX => format!("{nouns} {} and {}", shown[..n - 1].join(", "), shown[n - 1]),
            n => format!("{nouns} {} and {} more", shown.join(", "), n - MAX),
        }
    }

    /// Vertex `v` as a message names it, with its position.
    fn vertex(&self, v: u32) -> String {
        let p = at(self.vertices[v as usize]);
        match self.format {
            Format::Obj => format!("vertex {} {p}", v as u64 + 1),
            Format::StlAscii | Format::StlBinary => format!("welded vertex {v} {p}"),
        }
    }

    /// An error about triangle `t`: at its line, or naming it for binary STL.
    fn error_at(&self, t: usize, message: String) -> MeshError {
        MeshError::new(self.name, self.line(t), message)
    }

    /// The checked mesh, or the first thing wrong with it.
    pub(super) fn finish(mut self) -> Result<TriMesh, MeshError> {
        if self.triangles.is_empty() {
            return Err(MeshError::new(
                self.name,
                0,
                "the file holds no triangles; expected the closed surface of a solid",
            ));
        }
        self.check_degenerate()?;
        if let Err(open) = self.check_edges() {
            // An OBJ may give each triangle corners of its own, as an STL file does (some
            // exporters write one that way): a surface that is only closed once the corners at
            // the same position are one vertex. Welded as STL's are, it is checked again. A mesh
            // closed as written is never welded, so its vertices stay the file's.
            if self.format != Format::Obj || !self.weld_coincident() {
                return Err(open);
            }
            self.check_edges().map_err(|mut e| {
                e.message
                    .push_str(" (vertices at the same position taken as one, as in STL)");
                e
            })?;
        }
        self.drop_unused_vertices();

        // Orientation: a closed mesh encloses a non-zero volume whose sign says which way it is
        // wound; an inside-out one is flipped (which negates the volume exactly).
        let mut mesh = TriMesh {
            vertices: self.vertices,
            triangles: self.triangles,
        };
        let volume = mesh.volume();
        if !volume.is_finite() {
            let (lo, hi) = mesh.bounds();
            return Err(MeshError::new(
                self.name,
                0,
                format!(
                    "the enclosed volume is not a finite number ({volume}): the mesh, from {} to \
                     {}, is too large to measure in double precision",
                    at(lo),
                    at(hi)
                ),
            ));
        }
        if volume == 0.0 {
            return Err(MeshError::new(
                self.name,
                0,
                "the mesh is closed but encloses no volume (its shells cancel out, or the \
                 coordinates are too small to measure)",
            ));
        }
        if volume < 0.0 {
            for t in &mut mesh.triangles {
                t.swap(1, 2);
            }
        }
        Ok(mesh)
    }

    /// Every triangle has three distinct vertices and a non-zero area.
    fn check_degenerate(&self) -> Result<(), MeshError> {
        for (t, &[a, b, c]) in self.triangles.iter().enumerate() {
            let [pa, pb, pc] = [a, b, c].map(|v| self.vertices[v as usize]);
            if a == b || b == c || c == a {
                let twice = if a == b || a == c { a } else { b };
                let message = match self.format {
                    Format::Obj => format!(
                        "{} is degenerate: a triangle of it (vertices {}, {}, {}) uses vertex {} \
                         twice",
                        self.place(t),
                        a as u64 + 1,
                        b as u64 + 1,
                        c as u64 + 1,
                        twice as u64 + 1
                    ),
                    _ => format!(
                        "{} is degenerate: two of its corners are the same point {}",
                        self.place(t),
                        at(self.vertices[twice as usize])
                    ),
                };
                return Err(self.error_at(t, message));
            }
            if (pb - pa).cross(pc - pa) == Vec3::ZERO {
                return Err(self.error_at(
                    t,
                    format!(
                        "{} is degenerate: it has zero area (its corners {}, {}, {} lie on one \
                         line, or too close together to measure)",
                        self.place(t),
                        at(pa),
                        at(pb),
                        at(pc)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Every undirected edge is used by exactly two triangles, once in each direction, and no
    /// two triangles are the same triangle facing both ways. Reports the edge whose problem
    /// shows first in file order.
    fn check_edges(&self) -> Result<(), MeshError> {
        let tris = &self.triangles;
        // Half-edge h = 3·t + k runs from corner k of triangle t to corner k + 1.
        let from = |h: usize| tris[h / 3][h % 3];
        let to = |h: usize| tris[h / 3][(h % 3 + 1) % 3];
        let opposite = |h: usize| tris[h / 3][(h % 3 + 2) % 3];
        let key = |h: usize| {
            let (a, b) = (from(h), to(h));
            (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
        };

        // Sorting by (edge, half-edge) groups each edge's uses in file order.
        let mut half: Vec<(u64, usize)> = (0..3 * tris.len()).map(|h| (key(h), h)).collect();
        half.sort_unstable();

        // The first problem, by the half-edge that reveals it: the only use of an open edge,
        // the second use in one direction, the third use of a non-manifold edge.
        let mut first: Option<(usize, Problem, usize, usize)> = None;
        let mut start = 0;
        for group in half.chunk_by(|x, y| x.0 == y.0) {
            let hs = |i: usize| group[i].1;
            let found = match group.len() {
                1 => Some((hs(0), Problem::Open)),
                2 if (from(hs(0)) < to(hs(0))) == (from(hs(1)) < to(hs(1))) => {
                    Some((hs(1), Problem::Flipped))
                }
                2 if opposite(hs(0)) == opposite(hs(1)) => Some((hs(1), Problem::Sheet)),
                2 => None,
                _ => Some((hs(2), Problem::NonManifold)),
            };
            if let Some((h, problem)) = found {
                if first.is_none_or(|(f, ..)| h < f) {
                    first = Some((h, problem, start, group.len()));
                }
            }
            start += group.len();
        }
        let Some((h, problem, start, len)) = first else {
            return Ok(());
        };

        let edge = format!(
            "the edge from {} to {}",
            self.vertex(from(h)),
            self.vertex(to(h))
        );
        let ts: Vec<usize> = half[start..start + len]
            .iter()
            .map(|&(_, h)| h / 3)
            .collect();
        let message = match problem {
            Problem::Open => format!(
                "{edge} is used by one triangle only ({}): the surface has a hole there, so it \
                 does not enclose a solid (each edge must be shared by exactly two triangles)",
                self.places(&ts)
            ),
            Problem::Flipped => format!(
                "{edge} is used twice in the same direction (by {}): a triangle is flipped, the \
                 winding is inconsistent (each edge must be used once in each direction)",
                self.places(&ts)
            ),
            Problem::Sheet => format!(
                "{} and {} are the same triangle facing both ways: a sheet of no thickness \
                 encloses no solid",
                self.place(ts[0]),
                self.place(ts[1])
            ),
            Problem::NonManifold => format!(
                "{edge} is shared by {len} triangles ({}): the edge is non-manifold (the \
                 surface of a solid has exactly two triangles at each edge)",
                self.places(&ts)
            ),
        };
        Err(self.error_at(h / 3, message))
    }

    /// Makes the triangles use one vertex, the first in the file, for all the corners at the
    /// same position (`-0` equal to `0`, as the STL readers weld them); the others are left
    /// unused. Whether any two vertices were joined.
    fn weld_coincident(&mut self) -> bool {
        let mut first: std::collections::HashMap<[u64; 3], u32> = Default::default();
        // Adding +0 turns -0 into +0 and changes nothing else.
        let key = |p: Vec3| [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits);
        let same: Vec<u32> = (self.vertices.iter().enumerate())
            .map(|(v, &p)| *first.entry(key(p)).or_insert(v as u32))
            .collect();
        if first.len() == self.vertices.len() {
            return false;
        }
        for v in self.triangles.iter_mut().flatten() {
            *v = same[*v as usize];
        }
        true
    }

    /// Drops the vertices no triangle uses, keeping the order of the others.
    fn drop_unused_vertices(&mut self) {
        const UNUSED: u32 = u32::MAX;
        let mut new_index = vec![UNUSED; self.vertices.len()];
        for &v in self.triangles.iter().flatten() {
            new_index[v as usize] = 0;
        }
        if !new_index.contains(&UNUSED) {
            return;
        }
        let mut kept = 0;
        for (old, slot) in new_index.iter_mut().enumerate() {
            if *slot != UNUSED {
                *slot = kept;
                self.vertices[kept as usize] = self.vertices[old];
                kept += 1;
            }
        }
        self.vertices.truncate(kept as usize);
        for v in self.triangles.iter_mut().flatten() {
            *v = new_index[*v as usize];
        }
    }
}
