//! Helpers of the mesh readers' hostile-input tests: reads bounded by an allocation linear in
//! the input, error checks, meshes edited one triangle at a time, a generator of garbage.
//! A test binary includes it with `#[path = "common/hostile_mesh.rs"] mod hostile;` beside
//! `alloc_watch` and `meshes`.
#![allow(dead_code)]

use crate::alloc_watch::total_allocation;
use jello_core::{MeshError, TriMesh, Vec3};

pub const OBJ: &str = "hostile.obj";
pub const STL: &str = "hostile.stl";

/// Bytes any parse may allocate in all: [`ALLOCATION_PER_BYTE`] per byte of input plus
/// [`ALLOCATION_SLACK`]. The densest input is an OBJ polygon, one triangle per 2 bytes
/// (`f 1 2 3 4 …`), each triangle taking 12 bytes, its line 8, its vertex in the face 4 and its
/// three half-edges 48 in the edge check, vectors growing by doubling (so up to 3.5 times their
/// final size allocated in all): measured, 68 bytes per byte (`large_inputs_are_read_within_the_allocation_bound`); binary
/// STL, under 10. A reader that made words for a message before knowing there is an error (it
/// measured 114), copied the rest of the input per statement, or otherwise allocated more than
/// linearly, exceeds the bound. (Time is never measured: a hang shows as a test that never ends.)
pub const ALLOCATION_PER_BYTE: usize = 80;
pub const ALLOCATION_SLACK: usize = 64 << 10;

pub fn bounded(
    bytes: &[u8],
    read: impl FnOnce() -> Result<TriMesh, MeshError>,
) -> Result<TriMesh, MeshError> {
    let (r, total) = total_allocation(read);
    assert!(
        total <= ALLOCATION_PER_BYTE * bytes.len() + ALLOCATION_SLACK,
        "parsing {} bytes allocated {total} bytes",
        bytes.len()
    );
    r
}

pub fn obj(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    bounded(bytes, || TriMesh::parse_obj(bytes, OBJ))
}

pub fn stl(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    bounded(bytes, || TriMesh::parse_stl(bytes, STL))
}

/// Asserts `r` is an error from `name` at `line` (0: none) whose message contains every one of
/// `needles`; returns it.
pub fn expect_err(
    r: Result<TriMesh, MeshError>,
    name: &str,
    line: usize,
    needles: &[&str],
    what: &str,
) -> MeshError {
    let e = match r {
        Ok(m) => panic!(
            "{what}: parsed ({} triangles), expected an error",
            m.triangles.len()
        ),
        Err(e) => e,
    };
    let shown = e.to_string();
    assert_eq!(e.source_name, name, "{what}: {shown}");
    assert_eq!(e.line, line, "{what}: wrong line in {shown}");
    let prefix = if line > 0 {
        format!("{name}:{line}: ")
    } else {
        format!("{name}: ")
    };
    assert!(shown.starts_with(&prefix), "{what}: {shown:?}");
    for n in needles {
        assert!(
            e.message.contains(n),
            "{what}: {shown} does not mention {n:?}"
        );
    }
    e
}

/// Asserts `r` is an error naming `name`, whatever the line; returns it.
pub fn expect_any_err(r: Result<TriMesh, MeshError>, name: &str, what: &str) -> MeshError {
    match r {
        Ok(m) => panic!(
            "{what}: parsed ({} triangles), expected an error",
            m.triangles.len()
        ),
        Err(e) => {
            assert_eq!(e.source_name, name, "{what}: {e}");
            assert!(!e.message.is_empty(), "{what}");
            assert!(e.to_string().starts_with(name), "{what}: {e}");
            e
        }
    }
}

/// `m` with equal positions merged into their first vertex (for OBJ, which does not weld).
pub fn welded(m: &TriMesh) -> TriMesh {
    let mut vertices: Vec<Vec3> = Vec::new();
    let map: Vec<u32> = m
        .vertices
        .iter()
        .map(|p| match vertices.iter().position(|q| q == p) {
            Some(i) => i as u32,
            None => {
                vertices.push(*p);
                vertices.len() as u32 - 1
            }
        })
        .collect();
    TriMesh {
        vertices,
        triangles: m
            .triangles
            .iter()
            .map(|t| t.map(|i| map[i as usize]))
            .collect(),
    }
}

/// `m` without triangle `t`.
pub fn without(m: &TriMesh, t: usize) -> TriMesh {
    let mut out = m.clone();
    out.triangles.remove(t);
    out
}

/// `m` with triangle `t` wound the other way.
pub fn with_flipped(m: &TriMesh, t: usize) -> TriMesh {
    let mut out = m.clone();
    out.triangles[t].swap(1, 2);
    out
}

/// `m` with triangle `t` added at the end.
pub fn with_triangle(m: &TriMesh, t: [u32; 3]) -> TriMesh {
    let mut out = m.clone();
    out.triangles.push(t);
    out
}

/// A fixed-seed 64-bit LCG (Knuth's MMIX constants); the high bits are the output.
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }
    pub fn byte(&mut self) -> u8 {
        (self.next() >> 56) as u8
    }
    pub fn below(&mut self, n: u64) -> u64 {
        (self.next() >> 33) % n
    }
}

pub const NON_FINITE: &[&str] = &[
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "-Infinity",
    "1e400",
    "-1e400",
    "1e99999999999",
];
