//! The STL reader, ASCII and binary, and how the two are told apart (see
//! [`TriMesh::parse_stl`]).

use std::collections::HashMap;

use super::check::{at, Format, Raw};
use super::text::{check_text, number, strip_bom};
use super::{MeshError, TriMesh};
use crate::formats::world::{is_space, show, Tokens};
use crate::vec3::Vec3;

/// Bytes of a binary file's header, before the triangle count.
const HEADER: usize = 80;
/// Bytes before the first triangle: the header and the `u32` count.
const PREAMBLE: usize = HEADER + 4;
/// Bytes per triangle: normal, three corners (12 `f32`s), and a `u16` attribute.
const TRIANGLE: usize = 50;

/// Reads ASCII or binary STL; see [`TriMesh::parse_stl`].
pub(super) fn parse(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
    if starts_with_solid(bytes) {
        match ascii(bytes, name) {
            Ok(mesh) => return Ok(mesh),
            // Text that is not valid ASCII STL. A binary file whose header starts with "solid"
            // and whose numbers are all printable (only possible beyond 150 million triangles)
            // would be text too: the size decides.
            Err(AsciiError::Invalid(e)) => {
                if size_matches(bytes) {
                    if let Ok(mesh) = binary(bytes, name) {
                        return Ok(mesh);
                    }
                }
                return Err(e);
            }
            // Not text: a binary file whose header starts with "solid", as many do, or ASCII
            // STL with a bad byte. Binary if the size says so. Otherwise, a binary file of fewer
            // than 2²⁴ triangles has a zero byte in its count, so a bad byte beyond the count
            // (or a file too short for binary) means broken ASCII.
            Err(AsciiError::NotText(e, at)) => {
                if !size_matches(bytes) {
                    if at >= PREAMBLE || bytes.len() < PREAMBLE {
                        return Err(e);
                    }
                    let mut binary_error = binary(bytes, name).err().unwrap_or_else(|| e.clone());
                    binary_error.message = format!(
                        "{}; and although it starts with \"solid\", it is not ASCII STL either \
                         (line {}: {})",
                        binary_error.message, e.line, e.message
                    );
                    return Err(binary_error);
                }
            }
        }
    } else if !size_matches(bytes) {
        // Text that does not start with "solid" is not STL (an OBJ file named .stl, say):
        // saying so beats a binary header's count read from its letters.
        let body = strip_bom(bytes);
        if check_text(body).is_ok() {
            let mut tokens = Tokens::new(body);
            if let Some(t) = tokens.next_token() {
                return Err(MeshError::new(
                    name,
                    t.line,
                    format!(
                        "expected an ASCII STL file, starting with \"solid\", found {} (and \
                         the size does not fit binary STL either)",
                        show(t.text)
                    ),
                ));
            }
        }
    }
    binary(bytes, name)
}

/// Whether the file starts with `solid` (in any case), after an optional byte-order mark and
/// white space.
fn starts_with_solid(bytes: &[u8]) -> bool {
    let body = strip_bom(bytes);
    let start = body
        .iter()
        .position(|&b| !is_space(b))
        .unwrap_or(body.len());
    body[start..]
        .get(..5)
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"))
}

/// The triangle count of a binary file's header, if the file is long enough to hold one.
fn binary_count(bytes: &[u8]) -> Option<u32> {
    let count = bytes.get(HEADER..PREAMBLE)?;
    Some(u32::from_le_bytes([count[0], count[1], count[2], count[3]]))
}

/// Whether the file is exactly as long as its binary header's count says: `84 + 50·count`.
fn size_matches(bytes: &[u8]) -> bool {
    binary_count(bytes).is_some_and(|n| binary_size(n) == bytes.len() as u64)
}

/// The size of a binary file of `count` triangles (at most about 215 GB: no overflow).
fn binary_size(count: u32) -> u64 {
    PREAMBLE as u64 + TRIANGLE as u64 * u64::from(count)
}

/// Corners welded by exact equality of their coordinates.
struct Weld {
    /// Vertex index by the bits of its coordinates (`-0` made `+0`).
    index: HashMap<[u64; 3], u32>,
}

impl Weld {
    fn new() -> Self {
        Weld {
            index: HashMap::new(),
        }
    }

    /// The index of the vertex at `p` (finite), adding it to `raw` the first time.
    fn vertex(&mut self, raw: &mut Raw, p: Vec3, line: usize) -> Result<u32, MeshError> {
        // Adding +0 turns -0 into +0 and changes nothing else.
        let p = Vec3::new(p.x + 0.0, p.y + 0.0, p.z + 0.0);
        let key = p.to_array().map(f64::to_bits);
        if let Some(&i) = self.index.get(&key) {
            return Ok(i);
        }
        let i = raw.push_vertex(p, line)?;
        self.index.insert(key, i);
        Ok(i)
    }
}

// ---------------------------------------------------------------------------------------------
// ASCII.

/// Why an ASCII read failed: the bytes are not text at all (the offset of the first bad byte
/// given), or text that is not ASCII STL.
enum AsciiError {
    NotText(MeshError, usize),
    Invalid(MeshError),
}

/// Reads ASCII STL.
fn ascii(bytes: &[u8], name: &str) -> Result<TriMesh, AsciiError> {
    let body = strip_bom(bytes);
    let offset = bytes.len() - body.len();
    check_text(body)
        .map_err(|e| AsciiError::NotText(MeshError::new(name, e.line, e.message), offset + e.at))?;
    let mut r = AsciiReader {
        tokens: Tokens::new(body),
        raw: Raw::new(name, Format::StlAscii),
        weld: Weld::new(),
    };
    r.read().map_err(AsciiError::Invalid)?;
    r.raw.finish().map_err(AsciiError::Invalid)
}

/// The ASCII reader's cursor and the mesh so far.
struct AsciiReader<'a> {
    tokens: Tokens<'a>,
    raw: Raw<'a>,
    weld: Weld,
}

impl AsciiReader<'_> {
    fn error(&self, line: usize, message: String) -> MeshError {
        MeshError::new(self.raw.name, line, message)
    }

    /// `solid name`, facets, `endsolid name`; again for each further solid.
    fn read(&mut self) -> Result<(), MeshError> {
        self.keyword("solid", "")?;
        self.tokens.skip_line(); // the solid's name
        loop {
            let Some(t) = self.tokens.next_token() else {
                return Err(self.error(
                    self.tokens.line,
                    "expected \"facet\" or \"endsolid\", but the file ends here".into(),
                ));
            };
            if t.text.eq_ignore_ascii_case(b"facet") {
                self.facet(t.line)?;
            } else if t.text.eq_ignore_ascii_case(b"endsolid") {
                self.tokens.skip_line(); // the solid's name again
                match self.tokens.next_token() {
                    None => return Ok(()),
                    Some(t) if t.text.eq_ignore_ascii_case(b"solid") => self.tokens.skip_line(),
                    Some(t) => {
                        return Err(self.error(
                            t.line,
                            format!(
                                "expected another \"solid\" or the end of the file after \
                                 \"endsolid\", found {}",
                                show(t.text)
                            ),
                        ))
                    }
                }
            } else {
                return Err(self.error(
                    t.line,
                    format!("expected \"facet\" or \"endsolid\", found {}", show(t.text)),
                ));
            }
        }
    }

    /// The next token, which must be `word` (in any case); `why` is added to the error.
    fn keyword(&mut self, word: &str, why: &str) -> Result<(), MeshError> {
        match self.tokens.next_token() {
            Some(t) if t.text.eq_ignore_ascii_case(word.as_bytes()) => Ok(()),
            Some(t) => Err(self.error(
                t.line,
                format!("expected \"{word}\"{why}, found {}", show(t.text)),
            )),
            None => Err(self.error(
                self.tokens.line,
                format!("expected \"{word}\"{why}, but the file ends here"),
            )),
        }
    }

    /// A number, of any value when `finite` is false; `what` names it for an error, and is
    /// called only then (a file holds millions of numbers).
    fn number(&mut self, what: impl Fn() -> String, finite: bool) -> Result<f64, MeshError> {
        let Some(t) = self.tokens.next_token() else {
            return Err(self.error(
                self.tokens.line,
                format!("expected {}, but the file ends here", what()),
            ));
        };
        match number(t.text) {
            Some(v) if v.is_finite() || !finite => Ok(v),
            Some(_) => Err(self.error(
                t.line,
                format!("{}, {}, is not a finite number", what(), show(t.text)),
            )),
            None => Err(self.error(
                t.line,
                format!("expected {} (a number), found {}", what(), show(t.text)),
            )),
        }
    }

    /// After `facet` (on `line`): `normal n n n outer loop`, three `vertex x y z`, `endloop
    /// endfacet`. The normal may be any numbers: it is ignored.
    fn facet(&mut self, line: usize) -> Result<(), MeshError> {
        self.keyword("normal", " after \"facet\"")?;
        for axis in ["x", "y", "z"] {
            self.number(|| format!("the facet normal's {axis}"), false)?;
        }
        self.keyword("outer", "")?;
        self.keyword("loop", " after \"outer\"")?;
        let mut corners = [0; 3];
        for (k, corner) in corners.iter_mut().enumerate() {
            self.keyword("vertex", " (a facet has 3)")?;
            let vertex_line = self.tokens.line;
            let mut p = [0.0; 3];
            for (c, axis) in p.iter_mut().zip(["x", "y", "z"]) {
                *c = self.number(|| format!("vertex {}'s {axis} coordinate", k + 1), true)?;
            }
            *corner = self
                .weld
                .vertex(&mut self.raw, Vec3::from_array(p), vertex_line)?;
        }
        self.keyword("endloop", " (a facet has exactly 3 vertices)")?;
        self.keyword("endfacet", "")?;
        self.raw.push_triangle(corners, line);
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Binary.

/// Reads binary STL: the size must match the count exactly, checked before allocating.
fn binary(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
    let error = |message: String| MeshError::new(name, 0, message);
    let Some(count) = binary_count(bytes) else {
        return Err(error(format!(
            "not an STL file: it does not start with \"solid\" as ASCII STL does, and at {} \
             bytes it is too short for binary STL ({PREAMBLE} bytes at least: an 80-byte \
             header and a triangle count)",
            bytes.len()
        )));
    };
    let expected = binary_size(count);
    if expected != bytes.len() as u64 {
        return Err(error(format!(
            "binary STL: the header claims {count} triangles, which take {expected} bytes \
             ({PREAMBLE} + {TRIANGLE} per triangle), but the file has {} bytes (truncated, or \
             not an STL file)",
            bytes.len()
        )));
    }

    // The count is now bounded by the input's length.
    let mut raw = Raw::new(name, Format::StlBinary);
    raw.triangles.reserve_exact(count as usize);
    let mut weld = Weld::new();
    for (t, record) in bytes[PREAMBLE..].chunks_exact(TRIANGLE).enumerate() {
        let f = |o: usize| {
            f64::from(f32::from_le_bytes([
                record[o],
                record[o + 1],
                record[o + 2],
                record[o + 3],
            ]))
        };
        // Bytes 0..12 hold the normal, ignored; 48..50 the attribute, ignored.
        let mut corners = [0; 3];
        for (k, corner) in corners.iter_mut().enumerate() {
            let o = 12 + 12 * k;
            let p = Vec3::new(f(o), f(o + 4), f(o + 8));
            if !p.is_finite() {
                return Err(error(format!(
                    "triangle {}: corner {} is {}, which is not finite",
                    t + 1,
                    k + 1,
                    at(p)
                )));
            }
            *corner = weld.vertex(&mut raw, p, 0)?;
        }
        raw.push_triangle(corners, 0);
    }
    raw.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solid_is_found_after_a_byte_order_mark_and_white_space_in_any_case() {
        for yes in [
            &b"solid"[..],
            b"SOLID x",
            b"  \n\tsolid",
            b"\xef\xbb\xbfsolid",
            b"Solidworks",
        ] {
            assert!(
                starts_with_solid(yes),
                "{:?}",
                yes.escape_ascii().to_string()
            );
        }
        for no in [&b""[..], b"soli", b"x solid", b"\0solid", b"\xef\xbbsolid"] {
            assert!(
                !starts_with_solid(no),
                "{:?}",
                no.escape_ascii().to_string()
            );
        }
    }

    #[test]
    fn binary_size_is_84_plus_50_per_triangle_without_overflow() {
        assert_eq!(binary_size(0), 84);
        assert_eq!(binary_size(12), 684);
        assert_eq!(binary_size(u32::MAX), 84 + 50 * u64::from(u32::MAX));
        let mut bytes = vec![0; 84];
        assert!(size_matches(&bytes));
        bytes[80] = 1;
        assert!(!size_matches(&bytes));
        bytes.resize(134, 0);
        assert!(size_matches(&bytes));
        assert!(!size_matches(&bytes[..83]));
        assert_eq!(binary_count(&bytes[..83]), None);
    }
}
