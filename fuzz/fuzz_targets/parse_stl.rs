//! Fuzzes the STL reader: any bytes must parse or fail cleanly (an error naming the source and
//! an existing line); a mesh that parses must be the closed, consistently wound surface of a
//! solid with finite coordinates, indices in range and a positive volume, and must read back
//! the same (vertices numbered by first use) when written as ASCII STL and, if its coordinates
//! are `f32`s, as binary STL.
//!
//! Random bytes rarely have a binary file's exact size (84 + 50 per triangle), so each input is
//! also read with its count field rewritten to fit its length.
//!
//! Run with `scripts/fuzz.sh parse_stl` (or `cargo +nightly fuzz run parse_stl`) from the
//! repository root.

#![no_main]

mod mesh_checks;

use jello_core::TriMesh;
use libfuzzer_sys::fuzz_target;
use mesh_checks::{
    assert_clean_error, assert_solid, bits, renumbered_by_first_use, to_ascii_stl, to_binary_stl,
};

fn check(data: &[u8]) {
    let mesh = match TriMesh::parse_stl(data, "fuzz.stl") {
        Ok(m) => m,
        Err(e) => return assert_clean_error(&e, "fuzz.stl", data),
    };
    assert_solid(&mesh);
    let expected = renumbered_by_first_use(&mesh);
    let text = to_ascii_stl(&mesh);
    let again = TriMesh::parse_stl(text.as_bytes(), "again.stl")
        .unwrap_or_else(|e| panic!("written mesh does not re-parse: {e}\n{text}"));
    assert_eq!(bits(&again), bits(&expected), "re-parsed ASCII differs");
    if let Some(bytes) = to_binary_stl(&mesh) {
        let again = TriMesh::parse_stl(&bytes, "again.stl")
            .unwrap_or_else(|e| panic!("written binary mesh does not re-parse: {e}"));
        assert_eq!(bits(&again), bits(&expected), "re-parsed binary differs");
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    // The same bytes as a binary file whose count fits: header, count, whole triangles.
    if data.len() >= 80 {
        let count = (data.len() - 80) / 50;
        let mut bytes = data[..80].to_vec();
        bytes.extend((count as u32).to_le_bytes());
        bytes.extend(&data[80..80 + 50 * count]);
        check(&bytes);
    }
});
