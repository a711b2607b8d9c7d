//! Fuzzes the OBJ reader: any bytes must parse or fail cleanly (an error naming the source and
//! an existing line); a mesh that parses must be the closed, consistently wound surface of a
//! solid with finite coordinates, indices in range and a positive volume, and must read back
//! bit for bit when written as OBJ.
//!
//! Run with `scripts/fuzz.sh parse_obj` (or `cargo +nightly fuzz run parse_obj`) from the
//! repository root.

#![no_main]

mod mesh_checks;

use jello_core::TriMesh;
use libfuzzer_sys::fuzz_target;
use mesh_checks::{assert_clean_error, assert_solid, bits, to_obj};

fuzz_target!(|data: &[u8]| {
    let mesh = match TriMesh::parse_obj(data, "fuzz.obj") {
        Ok(m) => m,
        Err(e) => return assert_clean_error(&e, "fuzz.obj", data),
    };
    assert_solid(&mesh);
    // Outward already and every vertex used: written out, it reads back unchanged.
    let text = to_obj(&mesh);
    let again = TriMesh::parse_obj(text.as_bytes(), "again.obj")
        .unwrap_or_else(|e| panic!("written mesh does not re-parse: {e}\n{text}"));
    assert_eq!(bits(&again), bits(&mesh), "re-parsed mesh differs");
});
