//! An animated triangle mesh as one binary glTF 2.0 file (`.glb`) that Blender, three.js and
//! other glTF readers import as a single mesh whose shape plays back over time.
//!
//! The format's choice: **morph targets**. Frame 0 is the mesh itself (positions, normals,
//! triangles); every later frame is a morph target holding its displacement from frame 0, and
//! one animation drives the target weights: at frame `i`'s time, target `i` has weight 1 and the
//! others 0, with linear interpolation in between, so playback at any rate blends neighbouring
//! frames (positions move linearly from one frame to the next). One mesh object with shape keys
//! is what Blender's importer makes of it, which keeps the scene to one object however many
//! frames there are (a mesh per frame would make one object each). The weights are a sparse
//! accessor (one non-zero per frame), so the file grows linearly with the number of frames; a
//! reader expands them to `frames²` numbers, so one file holds at most [`MAX_FRAMES`] frames.
//! The morph targets hold positions only: readers recompute normals (Blender does), or shade
//! with frame 0's (three.js).
//!
//! Each body is a primitive of the mesh with a material of its own (a PBR base colour, the
//! viewer's: [`crate::colours`]), over the same vertices and morph targets, so that Blender
//! makes one object with a material slot per body. The animation's time accessor carries its
//! `min` and `max` (the first and last frame's times), as glTF requires of an animation input;
//! glTF has no field for a scene's frame range, so a reader that sets one from the file can only
//! take it from there.
//!
//! Positions are stored as 32-bit floats, as glTF requires for vertex data, and turned from
//! Jello's frame (z up) into glTF's (y up): `(x, y, z)` is written `(x, z, −y)`, which importers
//! such as Blender's turn back, so the jello stands the right way up. The JSON chunk is
//! written here by hand: its schema is fixed and every number in it is finite.

use std::fmt::Write as _;

use jello_core::model::skin::vertex_normals;
use jello_core::Vec3;

/// The most frames one file holds. A reader expands the sparse weights to `frames × (frames −
/// 1)` numbers (67 MB of them at this count), and the sparse indices are 32-bit.
pub const MAX_FRAMES: usize = 4096;

/// A part of the mesh drawn with a material of its own: a body.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshPart {
    /// The material's name (the body's).
    pub name: String,
    /// Where its triangles end in the mesh's list (they start where the previous part's end).
    pub triangles_end: usize,
    /// Its base colour, linear RGB (each 0 to 1).
    pub colour: [f32; 3],
}

/// Frames of a mesh of fixed topology, to be written as an animated glTF.
#[derive(Clone, Debug, Default)]
pub struct MeshAnimation {
    triangles: Vec<[u32; 3]>,
    vertices: usize,
    /// The parts, in the order of their triangles; none: the whole mesh is one part, coloured
    /// as the first body.
    parts: Vec<MeshPart>,
    /// Times (s), strictly increasing.
    times: Vec<f64>,
    /// Per frame, the positions of every vertex (f32, as stored).
    frames: Vec<Vec<[f32; 3]>>,
}

/// A frame that does not fit the animation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameError(pub String);

impl std::fmt::Display for FrameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FrameError {}

impl MeshAnimation {
    /// An animation of a mesh of `vertices` vertices and these triangles (indices below
    /// `vertices`, counter-clockwise seen from outside).
    pub fn new(vertices: usize, triangles: Vec<[u32; 3]>) -> Self {
        MeshAnimation {
            triangles,
            vertices,
            ..Default::default()
        }
    }

    /// The same animation with its triangles drawn as `parts` (each a body, with its material),
    /// in order; fails unless the parts' ends increase and the last is the triangle count.
    pub fn with_parts(mut self, parts: Vec<MeshPart>) -> Result<Self, FrameError> {
        let ends: Vec<usize> = parts.iter().map(|p| p.triangles_end).collect();
        let increasing = ends.windows(2).all(|w| w[0] <= w[1]);
        if !increasing || ends.last() != Some(&self.triangles.len()) {
            return Err(FrameError(format!(
                "parts ending at triangles {ends:?} do not cover the mesh's {} triangles in order",
                self.triangles.len()
            )));
        }
        if let Some(p) = parts
            .iter()
            .find(|p| !p.colour.iter().all(|c| (0.0..=1.0).contains(c)))
        {
            return Err(FrameError(format!(
                "part {}: colour {:?} is not linear RGB between 0 and 1",
                p.name, p.colour
            )));
        }
        self.parts = parts;
        Ok(self)
    }

    /// Number of frames so far.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True before the first frame.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Adds the frame at `time` (s). Fails when the positions are not one per vertex or not
    /// finite, when the time is not after the last frame's (in 32-bit floats, as stored), or
    /// beyond [`MAX_FRAMES`].
    pub fn push(&mut self, time: f64, positions: &[Vec3]) -> Result<(), FrameError> {
        if self.frames.len() == MAX_FRAMES {
            return Err(FrameError(format!(
                "more than {MAX_FRAMES} frames in one file"
            )));
        }
        if positions.len() != self.vertices {
            return Err(FrameError(format!(
                "a frame has {} positions for {} vertices",
                positions.len(),
                self.vertices
            )));
        }
        // Jello's z-up frame in glTF's y-up one.
        let frame: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| [p.x as f32, p.z as f32, -p.y as f32])
            .collect();
        if !time.is_finite() || frame.iter().flatten().any(|c| !c.is_finite()) {
            return Err(FrameError(format!(
                "the frame at t = {time} s is not finite in 32-bit floats"
            )));
        }
        if let Some(&last) = self.times.last() {
            if (time as f32) <= (last as f32) {
                return Err(FrameError(format!(
                    "frame times must increase: t = {time} s after t = {last} s"
                )));
            }
        }
        self.times.push(time);
        self.frames.push(frame);
        Ok(())
    }

    /// The binary glTF file. Needs at least one frame (with one frame, a still mesh).
    pub fn to_glb(&self, name: &str) -> Result<Vec<u8>, FrameError> {
        let Some(base) = self.frames.first() else {
            return Err(FrameError("no frame to write".into()));
        };
        if self.vertices == 0 || self.triangles.is_empty() {
            return Err(FrameError("the mesh has no triangles to write".into()));
        }
        if let Some(t) = self
            .triangles
            .iter()
            .find(|t| t.iter().any(|&v| v as usize >= self.vertices))
        {
            return Err(FrameError(format!(
                "triangle {t:?} refers to a vertex that does not exist"
            )));
        }
        let raw_name = name;
        let name = json_string(name);
        let mut bin = Binary::default();
        let mut views = Vec::new();
        let mut accessors = Vec::new();

        // Frame 0: positions (accessor 0) and smooth normals (1).
        let view = bin.view(&mut views, vec3s(base), Some(34962));
        accessors.push(vec3_accessor(view, base));
        let normals = normals(base, &self.triangles);
        let view = bin.view(&mut views, vec3s(&normals), Some(34962));
        accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5126,"count":{},"type":"VEC3"}}"#,
            normals.len()
        ));
        // Each part's triangles (a part with none is left out: glTF wants no empty accessor),
        // and its material.
        let whole = [MeshPart {
            name: raw_name.to_string(),
            triangles_end: self.triangles.len(),
            colour: crate::colours::body_colour(0),
        }];
        let parts = if self.parts.is_empty() {
            &whole[..]
        } else {
            &self.parts[..]
        };
        let mut drawn = Vec::new();
        let mut materials = Vec::new();
        let mut start = 0;
        for part in parts {
            let triangles = &self.triangles[start..part.triangles_end];
            start = part.triangles_end;
            if triangles.is_empty() {
                continue;
            }
            let indices: Vec<u32> = triangles.iter().flatten().copied().collect();
            let view = bin.view(&mut views, u32s(&indices), Some(34963));
            drawn.push((accessors.len(), materials.len()));
            accessors.push(format!(
                r#"{{"bufferView":{view},"componentType":5125,"count":{},"type":"SCALAR"}}"#,
                indices.len()
            ));
            let [r, g, b] = part.colour.map(json_f32);
            materials.push(format!(
                r#"{{"name":{},"pbrMetallicRoughness":{{"baseColorFactor":[{r},{g},{b},1],"metallicFactor":0,"roughnessFactor":0.5}}}}"#,
                json_string(&part.name)
            ));
        }
        // Later frames: displacements from frame 0.
        let mut targets = Vec::new();
        for frame in &self.frames[1..] {
            let delta: Vec<[f32; 3]> = frame
                .iter()
                .zip(base)
                .map(|(p, b)| [p[0] - b[0], p[1] - b[1], p[2] - b[2]])
                .collect();
            let view = bin.view(&mut views, vec3s(&delta), Some(34962));
            targets.push(format!(r#"{{"POSITION":{}}}"#, accessors.len()));
            accessors.push(vec3_accessor(view, &delta));
        }

        let frames = self.frames.len();
        let target_count = frames - 1;
        let mut animation = String::new();
        if target_count > 0 {
            // Key times, and per key the weights of all targets: one-hot, sparse.
            let times: Vec<f32> = self.times.iter().map(|&t| t as f32).collect();
            let view = bin.view(&mut views, f32s(&times), None);
            let input = accessors.len();
            accessors.push(format!(
                r#"{{"bufferView":{view},"componentType":5126,"count":{frames},"type":"SCALAR","min":[{}],"max":[{}]}}"#,
                json_f32(times[0]),
                json_f32(times[frames - 1])
            ));
            let hot: Vec<u32> = (1..frames)
                .map(|key| (key * target_count + (key - 1)) as u32)
                .collect();
            let index_view = bin.view(&mut views, u32s(&hot), None);
            let value_view = bin.view(&mut views, f32s(&vec![1.0; target_count]), None);
            let output = accessors.len();
            accessors.push(format!(
                r#"{{"componentType":5126,"count":{},"type":"SCALAR","sparse":{{"count":{target_count},"indices":{{"bufferView":{index_view},"componentType":5125}},"values":{{"bufferView":{value_view}}}}}}}"#,
                frames * target_count
            ));
            animation = format!(
                r#","animations":[{{"name":"simulation","channels":[{{"sampler":0,"target":{{"node":0,"path":"weights"}}}}],"samplers":[{{"input":{input},"output":{output},"interpolation":"LINEAR"}}]}}]"#
            );
        }

        // One primitive per part, all over the same vertices and morph targets.
        let targets = if targets.is_empty() {
            String::new()
        } else {
            format!(r#","targets":[{}]"#, targets.join(","))
        };
        let primitives: Vec<String> = drawn
            .iter()
            .map(|(indices, material)| {
                format!(
                    r#"{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":{indices},"material":{material},"mode":4{targets}}}"#
                )
            })
            .collect();
        let mut json = String::new();
        let _ = write!(
            json,
            r#"{{"asset":{{"version":"2.0","generator":"jello {}"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0,"name":{name}}}],"materials":[{}],"meshes":[{{"name":{name},"primitives":[{}]{}}}]{animation},"buffers":[{{"byteLength":{}}}],"bufferViews":[{}],"accessors":[{}]}}"#,
            env!("CARGO_PKG_VERSION"),
            materials.join(","),
            primitives.join(","),
            if target_count == 0 {
                String::new()
            } else {
                format!(r#","weights":[{}]"#, vec!["0"; target_count].join(","))
            },
            bin.data.len(),
            views.join(","),
            accessors.join(",")
        );
        if 12 + 8 + json.len() + 8 + bin.data.len() + 6 > u32::MAX as usize {
            return Err(FrameError(format!(
                "{} frames of {} vertices do not fit in one glTF file (4 GiB): export fewer \
                 frames per second",
                frames, self.vertices
            )));
        }
        Ok(glb(json.into_bytes(), bin.data))
    }
}

/// The binary chunk being laid out, 4-byte aligned.
#[derive(Default)]
struct Binary {
    data: Vec<u8>,
}

impl Binary {
    /// Appends `bytes` as a new buffer view (with `target` when it holds vertex data or
    /// indices) and returns its index.
    fn view(&mut self, views: &mut Vec<String>, bytes: Vec<u8>, target: Option<u32>) -> usize {
        let offset = self.data.len();
        self.data.extend_from_slice(&bytes);
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        let target = target.map_or(String::new(), |t| format!(r#","target":{t}"#));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}{target}}}"#,
            bytes.len()
        ));
        views.len() - 1
    }
}

/// A VEC3 float accessor with the bounds glTF requires for positions.
fn vec3_accessor(view: usize, values: &[[f32; 3]]) -> String {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in values {
        for c in 0..3 {
            lo[c] = lo[c].min(v[c]);
            hi[c] = hi[c].max(v[c]);
        }
    }
    let list = |a: [f32; 3]| a.map(json_f32).join(",");
    format!(
        r#"{{"bufferView":{view},"componentType":5126,"count":{},"type":"VEC3","min":[{}],"max":[{}]}}"#,
        values.len(),
        list(lo),
        list(hi)
    )
}

/// A finite `f32` as JSON (Rust's shortest round-trip form is valid JSON; `-0` becomes `0`).
fn json_f32(x: f32) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x:?}")
    }
}

/// `s` as a JSON string literal.
fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Smooth unit normals of frame 0 ([`vertex_normals`]), as stored.
fn normals(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let p: Vec<Vec3> = positions
        .iter()
        .map(|v| Vec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .collect();
    let mut n = vec![Vec3::ZERO; p.len()];
    vertex_normals(&p, triangles, &mut n);
    n.iter()
        .map(|u| [u.x as f32, u.y as f32, u.z as f32])
        .collect()
}

fn u32s(values: &[u32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn f32s(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn vec3s(values: &[[f32; 3]]) -> Vec<u8> {
    values
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// The GLB container: header, JSON chunk (padded with spaces), binary chunk (padded with 0).
fn glb(mut json: Vec<u8>, mut bin: Vec<u8>) -> Vec<u8> {
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetrahedron() -> MeshAnimation {
        MeshAnimation::new(4, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    }

    fn corners(shift: f64) -> Vec<Vec3> {
        [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]
        .map(|[x, y, z]| Vec3::new(x + shift, y, z))
        .to_vec()
    }

    /// The container: magic, version, total length, a JSON chunk padded with spaces and a binary
    /// chunk, both 4-byte aligned; the JSON names one morph target per later frame.
    #[test]
    fn glb_layout() {
        let mut a = tetrahedron();
        for (n, t) in [0.0, 0.5, 1.0].into_iter().enumerate() {
            a.push(t, &corners(n as f64 * 0.25)).unwrap();
        }
        let glb = a.to_glb("tet \"1\"").unwrap();
        let u32_at = |i: usize| u32::from_le_bytes(glb[i..i + 4].try_into().unwrap()) as usize;
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32_at(4), 2);
        assert_eq!(u32_at(8), glb.len());
        let json_len = u32_at(12);
        assert_eq!(&glb[16..20], b"JSON");
        assert_eq!(json_len % 4, 0);
        let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
        assert!(json.contains(r#""name":"tet \"1\"""#), "{json}");
        // Frame 0's attributes and one target per later frame.
        assert_eq!(json.matches(r#"{"POSITION":"#).count(), 3, "two targets");
        assert!(json.contains(r#""interpolation":"LINEAR""#));
        let bin_len = u32_at(20 + json_len);
        assert_eq!(&glb[24 + json_len..28 + json_len], b"BIN\0");
        assert_eq!(28 + json_len + bin_len, glb.len());
        assert_eq!(bin_len % 4, 0);
    }

    /// Parts: one primitive and material each, an empty part left out; parts that do not cover
    /// the triangles in order are refused.
    #[test]
    fn parts_are_primitives_with_their_materials() {
        let part = |name: &str, end, colour| MeshPart {
            name: name.into(),
            triangles_end: end,
            colour,
        };
        let parts = vec![
            part("a", 1, [1.0, 0.0, 0.0]),
            part("empty", 1, [0.0, 1.0, 0.0]),
            part("b", 4, [0.0, 0.0, 1.0]),
        ];
        let mut a = tetrahedron().with_parts(parts).unwrap();
        a.push(0.0, &corners(0.0)).unwrap();
        let glb = a.to_glb("t").unwrap();
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
        assert_eq!(json.matches(r#""material":"#).count(), 2, "{json}");
        assert!(
            json.contains(r#""name":"a","pbrMetallicRoughness":{"baseColorFactor":[1.0,0,0,1]"#)
        );
        assert!(
            json.contains(r#""name":"b","pbrMetallicRoughness":{"baseColorFactor":[0,0,1.0,1]"#)
        );
        assert!(!json.contains("empty"), "{json}");
        for bad in [
            vec![part("a", 3, [0.0; 3])],
            vec![
                part("a", 3, [0.0; 3]),
                part("b", 2, [0.0; 3]),
                part("c", 4, [0.0; 3]),
            ],
            vec![part("a", 4, [2.0, 0.0, 0.0])],
        ] {
            assert!(tetrahedron().with_parts(bad).is_err());
        }
    }

    #[test]
    fn bad_frames_are_refused() {
        let mut a = tetrahedron();
        assert!(a.to_glb("x").is_err(), "no frame");
        assert!(
            a.push(0.0, &corners(0.0)[..3]).is_err(),
            "too few positions"
        );
        let mut nan = corners(0.0);
        nan[2].y = f64::NAN;
        assert!(a.push(0.0, &nan).is_err());
        assert!(
            a.push(0.0, &[Vec3::new(1e39, 0.0, 0.0); 4]).is_err(),
            "beyond f32"
        );
        a.push(0.0, &corners(0.0)).unwrap();
        assert!(a.push(0.0, &corners(0.1)).is_err(), "time must increase");
        a.push(0.1, &corners(0.1)).unwrap();
        assert!(a.push(0.1 + 1e-12, &corners(0.2)).is_err(), "equal in f32");
        assert_eq!(a.len(), 2);
        let bad = MeshAnimation::new(3, vec![[0, 1, 3]]);
        let mut bad = bad;
        bad.push(0.0, &corners(0.0)[..3]).unwrap();
        assert!(bad.to_glb("x").is_err(), "index out of range");
    }
}
