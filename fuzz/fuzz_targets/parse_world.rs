//! Fuzzes the world-file reader: any bytes must parse or fail cleanly; a world that parses must
//! print to text that reads back to the same world bit for bit; and a world that makes a valid
//! simulation must survive one step (a blow-up is an `Err`, never a panic).
//!
//! Run with `cargo +nightly fuzz run parse_world` from the repository root.

#![no_main]

use jello_core::{step, Control, ReadOptions, Scratch, Vec3, World};
use libfuzzer_sys::fuzz_target;

fn vec_bits(v: &Vec3) -> [u64; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// Every number of the world as bits, in file order, so that `-0.0` and `0.0` differ.
fn bits(w: &World) -> Vec<u64> {
    let mut out = vec![
        w.dt.to_bits(),
        w.k_elastic.to_bits(),
        w.d_elastic.to_bits(),
        w.k_collision.to_bits(),
        w.d_collision.to_bits(),
        w.mass.to_bits(),
    ];
    if let Some(p) = w.plane {
        out.extend(p.map(f64::to_bits));
    }
    if let Some((res, forces)) = &w.field {
        out.push(*res as u64);
        out.extend(forces.iter().flat_map(vec_bits));
    }
    out.extend(w.positions.iter().flat_map(vec_bits));
    out.extend(w.velocities.iter().flat_map(vec_bits));
    out
}

fn check(data: &[u8], options: ReadOptions) {
    let world = match World::parse(data, "fuzz.w", options) {
        Ok(w) => w,
        Err(e) => {
            // Errors name the source; Display must not panic.
            let shown = e.to_string();
            assert!(shown.starts_with("fuzz.w"), "{shown}");
            return;
        }
    };

    // What parses prints back to the same world, bit for bit, and the text is a fixed point.
    let text = world.to_text();
    let again = World::parse(text.as_bytes(), "fuzz-again.w", ReadOptions::default())
        .unwrap_or_else(|e| panic!("to_text() does not re-parse: {e}\n{text}"));
    assert_eq!(again, world, "re-parsed world differs");
    assert_eq!(again.integrator, world.integrator);
    assert_eq!(again.steps_per_frame, world.steps_per_frame);
    assert_eq!(
        bits(&again),
        bits(&world),
        "re-parsed world differs in bits"
    );
    assert_eq!(again.to_text(), text, "to_text() is not a fixed point");

    // A valid simulation survives one step: Ok or a reported blow-up.
    if let Ok((model, mut state)) = world.to_simulation() {
        let mut scratch = Scratch::new(&model);
        let _ = step(&model, &mut state, &Control::none(), &mut scratch);
    }
}

fuzz_target!(|data: &[u8]| {
    check(data, ReadOptions::default());
    // With an override, unknown integrator words are accepted: exercise that path too.
    if data.first().is_some_and(|b| b.is_ascii_alphabetic()) {
        check(
            data,
            ReadOptions {
                integrator: Some(jello_core::Integrator::Euler),
            },
        );
    }
});
