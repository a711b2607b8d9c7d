//! Fuzzes the scene reader: any bytes must parse or fail cleanly (an error naming the source,
//! with a line inside the text); a scene that parses must write back as TOML that reads back
//! equal, and, when small, must become a model or fail with an error, never a panic.
//!
//! Run with `scripts/fuzz.sh parse_scene` (or `cargo +nightly fuzz run parse_scene`) from the
//! repository root.

#![no_main]

use jello_core::SceneFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let scene = match SceneFile::parse(data, "fuzz.toml") {
        Ok(s) => s,
        Err(e) => {
            assert_eq!(e.source_name, "fuzz.toml");
            let lines = data.split(|&b| b == b'\n').count();
            assert!(e.line <= lines, "error line {} past the end ({lines} lines)", e.line);
            assert!(!e.message.is_empty());
            return;
        }
    };
    let text = scene.to_toml();
    let again = SceneFile::parse(text.as_bytes(), "again.toml")
        .unwrap_or_else(|e| panic!("written scene does not re-parse: {e}\n{text}"));
    // NaN never equals itself; compare the written forms instead.
    assert_eq!(again.to_toml(), text, "re-parsed scene differs");
    // Making the model voxelises meshes and allocates lattices: only for small scenes.
    let small = scene.bodies.len() <= 4
        && scene.bodies.iter().all(|b| {
            b.mesh.as_ref().is_none_or(|m| m.cells <= 12 && m.triangles.len() <= 256)
                && b.cube.is_none_or(|c| c.points.iter().all(|&n| n <= 16))
        })
        && scene.field.as_ref().is_none_or(|f| f.resolution <= 8);
    if small {
        let _ = scene.to_scene("fuzz.toml");
    }
});
