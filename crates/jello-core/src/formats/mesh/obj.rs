//! The Wavefront OBJ reader: what it understands and ignores is listed at
//! [`TriMesh::parse_obj`].

use super::check::{Format, Raw};
use super::text::{check_text, number, strip_bom};
use super::{MeshError, TriMesh};
use crate::formats::world::{is_space, show};
use crate::vec3::Vec3;

/// Statements that say nothing about the surface: points and lines (which bound no solid),
/// grouping, materials and the other display and render attributes.
const IGNORED: &[&[u8]] = &[
    b"l",
    b"p",
    b"o",
    b"g",
    b"s",
    b"mg",
    b"usemtl",
    b"mtllib",
    b"usemap",
    b"maplib",
    b"lod",
    b"bevel",
    b"c_interp",
    b"d_interp",
    b"shadow_obj",
    b"trace_obj",
    b"ctech",
    b"stech",
];

/// Free-form geometry statements: curves and surfaces this reader cannot triangulate.
const FREE_FORM: &[&[u8]] = &[
    b"cstype", b"deg", b"bmat", b"step", b"curv", b"curv2", b"surf", b"parm", b"trim", b"hole",
    b"scrv", b"sp", b"end", b"con",
];

/// The reader's state: the mesh so far, and how many texture coordinates and normals are
/// defined (faces refer to them by number).
struct Reader<'a> {
    raw: Raw<'a>,
    texcoords: usize,
    normals: usize,
    /// The current face's vertices (kept to reuse its allocation).
    face: Vec<u32>,
}

/// Reads OBJ text; see [`TriMesh::parse_obj`].
pub(super) fn parse(bytes: &[u8], name: &str) -> Result<TriMesh, MeshError> {
    let text = check_text(strip_bom(bytes)).map_err(|e| MeshError::new(name, e.line, e.message))?;
    let mut r = Reader {
        raw: Raw::new(name, Format::Obj),
        texcoords: 0,
        normals: 0,
        face: Vec::new(),
    };
    // A statement ending in a backslash continues on the next line: (its first line, its text).
    let mut continued: Option<(usize, String)> = None;
    for (i, line) in text.split('\n').enumerate() {
        // `#` starts a comment anywhere (a backslash inside a comment continues nothing).
        let line = line.split_once('#').map_or(line, |(code, _)| code);
        let code = line.trim_end_matches(|c: char| c.is_ascii() && is_space(c as u8));
        if let Some(head) = code.strip_suffix('\\') {
            let (_, buffer) = continued.get_or_insert_with(|| (i + 1, String::new()));
            buffer.push_str(head);
            buffer.push(' ');
            continue;
        }
        match continued.take() {
            Some((first, mut buffer)) => {
                buffer.push_str(line);
                r.statement(buffer.as_bytes(), first)?;
            }
            None => r.statement(line.as_bytes(), i + 1)?,
        }
    }
    if let Some((first, buffer)) = continued {
        r.statement(buffer.as_bytes(), first)?;
    }
    r.raw.finish()
}

/// `n` and a noun, singular or plural.
fn count(n: usize, one: &str, many: &str) -> String {
    if n == 1 {
        format!("1 {one}")
    } else {
        format!("{n} {many}")
    }
}

/// A decimal integer with an optional sign, saturating at the ends of `i64` (a huge index is out
/// of range all the same); `None` unless it is one.
fn integer(text: &[u8]) -> Option<i64> {
    let (negative, digits) = match text.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, text),
    };
    if digits.is_empty() || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let magnitude = digits.iter().fold(0i64, |n, d| {
        n.saturating_mul(10).saturating_add(i64::from(d - b'0'))
    });
    Some(if negative { -magnitude } else { magnitude })
}

impl Reader<'_> {
    fn error(&self, line: usize, message: String) -> MeshError {
        MeshError::new(self.raw.name, line, message)
    }

    /// One statement (a line, or lines joined by backslashes) starting on `line`.
    fn statement(&mut self, text: &[u8], line: usize) -> Result<(), MeshError> {
        let mut tokens = text.split(|&b| is_space(b)).filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else {
            return Ok(()); // blank, or a comment
        };
        match keyword {
            b"v" => self.vertex(tokens, line),
            b"f" | b"fo" => self.face(tokens, line),
            b"vt" => {
                self.texcoords += 1;
                Ok(())
            }
            b"vn" => {
                self.normals += 1;
                Ok(())
            }
            b"vp" => Ok(()),
            k if IGNORED.contains(&k) => Ok(()),
            k if FREE_FORM.contains(&k) => Err(self.error(
                line,
                format!(
                    "free-form geometry ({}) is not supported: export the surface as polygons",
                    show(k)
                ),
            )),
            k => Err(self.error(
                line,
                format!(
                    "unknown statement {}: expected v or f (vt, vn, vp, l, p, o, g, s, mg, \
                     usemtl, mtllib and display attributes are ignored)",
                    show(k)
                ),
            )),
        }
    }

    /// `v x y z`, then optionally `w`, or a colour `r g b [a]`: at most 7 numbers, all finite.
    fn vertex<'t>(
        &mut self,
        tokens: impl Iterator<Item = &'t [u8]>,
        line: usize,
    ) -> Result<(), MeshError> {
        const MOST: usize = 7;
        let mut xyz = [0.0; 3];
        let mut n = 0;
        // Names the n-th number for an error (made only then: a file may hold millions).
        let what = |n: usize| match n {
            0..3 => format!("the vertex's {} coordinate", ["x", "y", "z"][n]),
            n => format!("number {} of the vertex", n + 1),
        };
        for token in tokens {
            if n == MOST {
                return Err(self.error(
                    line,
                    format!(
                        "a vertex has at most {MOST} numbers (x y z, then w or a colour r g b \
                         [a]); found more: {}",
                        show(token)
                    ),
                ));
            }
            match number(token) {
                Some(v) if v.is_finite() => {
                    if n < 3 {
                        xyz[n] = v;
                    }
                }
                Some(_) => {
                    return Err(self.error(
                        line,
                        format!("{}, {}, is not a finite number", what(n), show(token)),
                    ))
                }
                None => {
                    return Err(self.error(
                        line,
                        format!("expected {} (a number), found {}", what(n), show(token)),
                    ))
                }
            }
            n += 1;
        }
        if n < 3 {
            return Err(self.error(
                line,
                format!(
                    "a vertex needs x, y and z coordinates; found {}",
                    count(n, "number", "numbers")
                ),
            ));
        }
        self.raw.push_vertex(Vec3::from_array(xyz), line)?;
        Ok(())
    }

    /// `f a b c …`: a polygon of 3 or more vertex references, fanned into triangles.
    fn face<'t>(
        &mut self,
        tokens: impl Iterator<Item = &'t [u8]>,
        line: usize,
    ) -> Result<(), MeshError> {
        let mut face = std::mem::take(&mut self.face);
        face.clear();
        for token in tokens {
            face.push(self.reference(token, line)?);
        }
        if face.len() < 3 {
            return Err(self.error(
                line,
                format!(
                    "a face needs at least 3 vertices; found {}",
                    count(face.len(), "vertex", "vertices")
                ),
            ));
        }
        for k in 1..face.len() - 1 {
            self.raw
                .push_triangle([face[0], face[k], face[k + 1]], line);
        }
        self.face = face;
        Ok(())
    }

    /// A vertex reference `v`, `v/vt`, `v//vn` or `v/vt/vn`: the vertex's 0-based index. The
    /// texture coordinate and normal must exist but are not used.
    fn reference(&self, token: &[u8], line: usize) -> Result<u32, MeshError> {
        let malformed = || {
            self.error(
                line,
                format!(
                    "expected a vertex reference (v, v/vt, v//vn or v/vt/vn, with non-zero \
                     integers), found {}",
                    show(token)
                ),
            )
        };
        let mut parts = token.split(|&b| b == b'/');
        let v = parts.next().unwrap_or_default();
        let (vt, vn) = (parts.next(), parts.next());
        if parts.next().is_some() {
            return Err(malformed());
        }
        let index = |part: &[u8], defined: usize, one: &str, many: &str| {
            let i = integer(part).ok_or_else(malformed)?;
            self.resolve(i, part, defined, one, many, line)
        };
        let vertex = index(v, self.raw.vertices.len(), "vertex", "vertices")?;
        match (vt, vn) {
            (None, _) => {}
            // `v//vn`: no texture coordinate.
            (Some(b""), Some(vn)) => {
                index(vn, self.normals, "normal", "normals")?;
            }
            (Some(vt), vn) => {
                index(
                    vt,
                    self.texcoords,
                    "texture coordinate",
                    "texture coordinates",
                )?;
                if let Some(vn) = vn {
                    index(vn, self.normals, "normal", "normals")?;
                }
            }
        }
        // Below the vertex count, which `Raw::push_vertex` keeps below `u32::MAX`.
        Ok(vertex as u32)
    }

    /// Index `i` (written `text`) of an element of which `defined` exist so far: 0-based.
    fn resolve(
        &self,
        i: i64,
        text: &[u8],
        defined: usize,
        one: &str,
        many: &str,
        line: usize,
    ) -> Result<usize, MeshError> {
        let magnitude = usize::try_from(i.unsigned_abs()).unwrap_or(usize::MAX);
        match i {
            i if i > 0 && magnitude <= defined => return Ok(magnitude - 1),
            i if i < 0 && magnitude <= defined => return Ok(defined - magnitude),
            _ => {}
        }
        // An error: only now are the words for it made (a face may have a million indices).
        let shown = if text.len() <= 24 {
            String::from_utf8_lossy(text).into_owned()
        } else {
            show(text)
        };
        let defines = format!(
            "the file defines {} before this line",
            count(defined, one, many)
        );
        match i {
            0 => Err(self.error(
                line,
                format!(
                    "{one} index 0 is invalid: OBJ counts {many} from 1 (and back from the last \
                     one with negative numbers)"
                ),
            )),
            1.. => Err(self.error(
                line,
                format!("{one} index {shown} is out of range: {defines}"),
            )),
            _ => Err(self.error(
                line,
                format!(
                    "{one} index {shown} is out of range: it counts back past the first one, and \
                     {defines}"
                ),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::integer;

    #[test]
    fn integers_saturate_and_reject_what_is_not_one() {
        assert_eq!(integer(b"12"), Some(12));
        assert_eq!(integer(b"-3"), Some(-3));
        assert_eq!(integer(b"+7"), Some(7));
        assert_eq!(integer(b"-0"), Some(0));
        assert_eq!(integer(b"99999999999999999999"), Some(i64::MAX));
        assert_eq!(integer(b"-99999999999999999999"), Some(-i64::MAX));
        for bad in [
            &b""[..],
            b"-",
            b"+",
            b"1.0",
            b"1e3",
            b" 1",
            b"0x1",
            b"--1",
            b"1-",
        ] {
            assert_eq!(integer(bad), None, "{:?}", bad.escape_ascii().to_string());
        }
    }
}
