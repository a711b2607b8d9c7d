//! `jello run --export OUT.glb` read back: the file's JSON chunk, parsed, gives each body a
//! material of its own (the viewer's colour) and its own primitive over the shared vertices and
//! morph targets, and an animation whose time accessor spans the run.

use std::fs;

use serde_json::Value;

mod common;

use common::TempDir;

/// The JSON chunk of a GLB file, parsed.
fn glb_json(bytes: &[u8]) -> Value {
    assert_eq!(&bytes[0..4], b"glTF");
    let length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + length]).unwrap()
}

#[test]
fn each_body_has_its_material_and_the_animation_spans_the_run() {
    let t = TempDir::new("export");
    t.succeeds(&[
        "create", "two.toml", "--cube", "3", "--size", "0.4", "--centre", "0,0,0", "--name",
        "left", "--cube", "4", "--size", "0.4", "--centre", "1,0,0", "--name", "right",
    ]);
    t.succeeds(&[
        "run", "two.toml", "--time", "0.2", "--export", "two.glb", "-q",
    ]);
    let json = glb_json(&fs::read(t.path("two.glb")).unwrap());

    // A material per body, named after it, with the viewer's colours in linear light.
    let materials = json["materials"].as_array().unwrap();
    assert_eq!(materials.len(), 2);
    for (b, (material, name)) in materials.iter().zip(["left", "right"]).enumerate() {
        assert_eq!(material["name"], name);
        let colour = &material["pbrMetallicRoughness"]["baseColorFactor"];
        let want = jello_io::colours::body_colour(b);
        for c in 0..3 {
            assert_eq!(colour[c].as_f64().unwrap() as f32, want[c], "{name}");
        }
        assert_eq!(colour[3], 1.0);
    }
    assert_ne!(
        materials[0]["pbrMetallicRoughness"],
        materials[1]["pbrMetallicRoughness"]
    );

    // A primitive per body over the same vertices and targets: a 3³ cube's surface has 6·2·2·2
    // triangles, a 4³ cube's 6·3·3·2.
    let primitives = json["meshes"][0]["primitives"].as_array().unwrap();
    assert_eq!(primitives.len(), 2);
    let accessors = json["accessors"].as_array().unwrap();
    for (b, (primitive, triangles)) in primitives.iter().zip([48, 108]).enumerate() {
        assert_eq!(primitive["material"], b);
        assert_eq!(primitive["attributes"], primitives[0]["attributes"]);
        assert_eq!(primitive["targets"], primitives[0]["targets"]);
        let indices = &accessors[primitive["indices"].as_u64().unwrap() as usize];
        assert_eq!(indices["count"], 3 * triangles);
    }
    let frames = primitives[0]["targets"].as_array().unwrap().len() + 1;
    // 0.2 s at dt 0.0005 is 400 steps, a frame every 67 (30 fps): 0, 67, …, 335, and the end.
    assert_eq!(frames, 7);

    // The animation's time accessor spans the run: min 0, max 0.2 s.
    let sampler = &json["animations"][0]["samplers"][0];
    let input = &accessors[sampler["input"].as_u64().unwrap() as usize];
    assert_eq!(input["count"], frames);
    assert_eq!(input["min"][0], 0.0);
    let end = input["max"][0].as_f64().unwrap();
    assert!((end - 0.2).abs() < 1e-6, "{end}");
}
