//! Closed triangle meshes: the surface of a solid, read from OBJ or STL (ASCII or binary).
//!
//! A reader takes the bytes of a file and a name for its messages (the crate does no I/O) and
//! returns a [`TriMesh`] only when the mesh is the closed, consistently oriented surface of a
//! solid; otherwise a [`MeshError`] says where and what is wrong, like [`crate::WorldError`]:
//! `"name:line: message"`, or `"name: message"` when no line applies (a binary file, or the
//! whole file).
//!
//! Every mesh a reader returns satisfies, and its tests and fuzz targets check:
//! - at least one triangle, every coordinate finite, every index in range, every vertex a corner
//!   of some triangle (vertices no face uses are dropped; the others keep their order);
//! - no degenerate triangle: three distinct vertices, and a cross product of two edges that is
//!   not exactly zero (corners on one line, or so close that the area underflows, are an error);
//! - closed and consistently oriented: every undirected edge is used by exactly two triangles,
//!   once in each direction. A hole (an edge used once), a non-manifold edge (used three or more
//!   times), a flipped triangle (an edge used twice in the same direction) and a triangle repeated
//!   facing the other way (a sheet of no thickness) are each an error naming the first offending
//!   edge, in the order the triangles come in the file, with its vertices and their positions;
//! - [`TriMesh::volume`] finite and positive. A mesh wound inside-out (negative volume) is not an
//!   error: every triangle is flipped and the mesh accepted. Orientation is decided for the mesh
//!   as a whole, so a second shell wound against the first is taken as a cavity.
//!
//! Not checked: self-intersection, and vertices where two shells touch at a point (two cubes
//! sharing a corner bound a solid, and are accepted).
//!
//! Allocation is bounded by the input's length (a binary header's triangle count is checked
//! against the file size before anything is allocated for it), and every step is linear in the
//! input, up to a sort of the edges.

mod check;
mod obj;
mod shapes;
mod stl;
mod text;

pub use shapes::SHAPES;

use std::fmt;

use crate::vec3::Vec3;

/// A closed triangle mesh: the surface of a solid.
#[derive(Clone, Debug, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (m).
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside (normals
    /// outward).
    pub triangles: Vec<[u32; 3]>,
}

/// A mesh file that could not be read, or a mesh that is not the closed surface of a solid.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshError {
    /// The file name (or other label) the bytes came from.
    pub source_name: String,
    /// 1-based line of the offending statement; 0 when the error is about the whole file, or the
    /// file is binary (the message then names the triangle).
    pub line: usize,
    /// What was expected and what was found.
    pub message: String,
}

impl MeshError {
    /// An error at `line` (0: none) of `source_name`.
    pub(crate) fn new(source_name: &str, line: usize, message: impl Into<String>) -> Self {
        MeshError {
            source_name: source_name.to_string(),
            line,
            message: message.into(),
        }
    }
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: {}", self.source_name, self.line, self.message)
        } else {
            write!(f, "{}: {}", self.source_name, self.message)
        }
    }
}

impl std::error::Error for MeshError {}

/// The extensions [`TriMesh::parse`] knows, lower case, each with its reader.
type Reader = fn(&[u8], &str) -> Result<TriMesh, MeshError>;
const FORMATS: [(&str, Reader); 2] = [("obj", TriMesh::parse_obj), ("stl", TriMesh::parse_stl)];

impl TriMesh {
    /// Reads a Wavefront OBJ file; `name` labels errors (usually the path).
    ///
    /// Understood: `v x y z` (an optional `w`, or the common `r g b` colour extension, may
    /// follow: up to 7 numbers, all finite), and `f` (and its old synonym `fo`) with 3 or more
    /// vertex references `v`, `v/vt`, `v//vn` or `v/vt/vn`; indices count from 1, negative ones
    /// back from the last element defined so far, and must refer to an element defined before
    /// the face. A polygon `f a b c d …` is fanned into triangles `(a, b, c), (a, c, d), …`.
    /// `#` starts a comment anywhere on a line, and a line ending in `\` continues on the next
    /// (errors in it then name its first line). Ignored: `vt`, `vn` and `vp` (counted, so that
    /// face references to them are range-checked), `l`, `p`, `o`, `g`, `s`, `mg`, `usemtl`,
    /// `mtllib` and the other display attributes of the specification (`usemap`, `maplib`,
    /// `lod`, `bevel`, `c_interp`, `d_interp`, `shadow_obj`, `trace_obj`, `ctech`, `stech`).
    /// Free-form geometry (`cstype`, `surf`, `curv`, …) is an error: its surfaces would be
    /// missing from the mesh. Any other keyword is an error too, naming it, so that a misspelt
    /// or unsupported statement is not silently dropped.
    ///
    /// The file must be UTF-8 text (an optional byte-order mark is skipped); invalid UTF-8 and
    /// control characters are errors at their line. Vertex order is the file's, less the vertices
    /// no face uses.
    ///
    /// A file whose faces do not share their corners (each triangle with vertices of its own, as
    /// some exporters write, and as STL always is) is not closed as written; it is then welded as
    /// STL is, the corners at exactly the same position (`-0` equal to `0`) made the first such
    /// vertex of the file, and checked again. A mesh closed as written is never welded.
    pub fn parse_obj(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
        obj::parse(bytes, name)
    }

    /// Reads an STL file, ASCII or binary; `name` labels errors (usually the path).
    ///
    /// ASCII ("solid" ... "facet normal" ... "endsolid") or binary (80-byte header, u32 count,
    /// 50 bytes per triangle), told apart robustly (a binary file may start with "solid": decide
    /// by whether the size matches 84 + 50·count and the text parses).
    ///
    /// In detail: a file starting with `solid` (after an optional byte-order mark and white
    /// space) is read as ASCII; if that fails, it is read as binary when its size is exactly
    /// `84 + 50·count`, or when it is not text at all, and the binary reader's answer is taken
    /// unless the file is text (then the ASCII error is the useful one). Anything else is binary,
    /// whose size must match its count exactly.
    ///
    /// ASCII keywords match in any case; a file may hold several `solid … endsolid` blocks,
    /// which make one mesh; errors name the line. In binary files, coordinates are `f32` widened
    /// exactly to `f64`, and errors name the triangle, counted from 1. In both, the facet normal
    /// (and the binary attribute word) is ignored: the winding decides the outside. Corners are
    /// welded by exact equality of their coordinates (`-0` equals `0`), so that triangles share
    /// vertices; vertices are numbered in the order they first appear, and messages give these
    /// numbers counted from 0.
    pub fn parse_stl(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
        stl::parse(bytes, name)
    }

    /// A mesh from vertex positions and triangles held in memory (a scene file's embedded mesh),
    /// with the same checks as the readers: finite coordinates, indices in range, and a closed,
    /// manifold, consistently oriented surface (then unused vertices are dropped and an
    /// inside-out mesh is flipped). Errors name triangles counted from 1; `name` labels them.
    pub fn from_parts(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        name: &str,
    ) -> Result<TriMesh, MeshError> {
        let mut raw = check::Raw::new(name, check::Format::StlBinary);
        for (v, &p) in vertices.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::new(
                    name,
                    0,
                    format!("vertex {v} (counted from 0) has a coordinate that is not finite"),
                ));
            }
            raw.push_vertex(p, 0)?;
        }
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v as usize >= vertices.len()) {
                return Err(MeshError::new(
                    name,
                    0,
                    format!(
                        "triangle {} refers to vertex {v}, but there are {} (counted from 0)",
                        t + 1,
                        vertices.len()
                    ),
                ));
            }
            raw.push_triangle(*tri, 0);
        }
        raw.finish()
    }

    /// Reads a mesh file, choosing the reader by the extension of `name` (`.obj` or `.stl`, in
    /// any case); an unknown or missing extension is an error naming the known ones.
    pub fn parse(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
        let file = name.rsplit(['/', '\\']).next().unwrap_or(name);
        let extension = file.rsplit_once('.').map(|(_, e)| e);
        if let Some(e) = extension {
            for (known, reader) in FORMATS {
                if e.eq_ignore_ascii_case(known) {
                    return reader(bytes, name);
                }
            }
        }
        let known: Vec<String> = FORMATS.iter().map(|(e, _)| format!(".{e}")).collect();
        let found = match extension {
            Some(e) => format!(
                "an unknown extension {}",
                crate::formats::world::show(format!(".{e}").as_bytes())
            ),
            None => "no extension".to_string(),
        };
        Err(MeshError::new(
            name,
            0,
            format!(
                "cannot tell the mesh format: the name has {found}; expected one of {} (in any case)",
                known.join(", ")
            ),
        ))
    }

    /// Signed enclosed volume (m³) by the divergence theorem; positive for an outward-wound
    /// closed mesh.
    ///
    /// The sum of the signed volumes of the tetrahedra joining each triangle to the centre of the
    /// bounding box (rather than the origin, so that a small mesh far from the origin loses no
    /// precision). Flipping every triangle negates it exactly. Meaningful for a closed mesh only.
    ///
    /// # Panics
    /// If a triangle's index is out of range (never for a mesh a reader returned).
    pub fn volume(&self) -> f64 {
        crate::model::skin::enclosed_volume(&self.vertices, &self.triangles)
    }

    /// Smallest and largest coordinates of the vertices.
    ///
    /// Both are zero for a mesh without vertices (never one a reader returned).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let Some(&first) = self.vertices.first() else {
            return (Vec3::ZERO, Vec3::ZERO);
        };
        self.vertices.iter().fold((first, first), |(lo, hi), p| {
            (
                Vec3::new(lo.x.min(p.x), lo.y.min(p.y), lo.z.min(p.z)),
                Vec3::new(hi.x.max(p.x), hi.y.max(p.y), hi.z.max(p.z)),
            )
        })
    }
}
