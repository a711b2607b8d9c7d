//! Sets the cfg `shared_worlds` when the corpus of world files from the wild is beside the
//! repository (`../shared/worlds`): the tests that read it run then, and are listed as ignored,
//! with the reason, when it is absent (a clean clone on its own).
//!
//! The check runs when this crate is first built: after `../shared` appears, `cargo clean -p
//! <crate>` makes it look again (watching a path that is absent would rebuild the crate every
//! time).

use std::path::Path;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(shared_worlds)");
    println!("cargo::rerun-if-changed=build.rs");
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let worlds = Path::new(&manifest).join("../../../shared/worlds");
    if worlds.is_dir() {
        println!("cargo::rustc-cfg=shared_worlds");
        println!("cargo::rerun-if-changed={}", worlds.display());
    }
}
