//! Where bodies start, against coordinates worked out by hand: `rotation_xyz` turns about x, then
//! y, then z; a scene body's rest box is turned about its middle and its middle put at `centre`;
//! a spin adds `ω × (p − centre of mass)` to every point's velocity.

use jello_core::model::body::rotation_xyz;
use jello_core::{SceneFile, Vec3};

/// `R·v` for rows `r`.
fn turn(r: [Vec3; 3], v: Vec3) -> Vec3 {
    Vec3::new(r[0].dot(v), r[1].dot(v), r[2].dot(v))
}

fn assert_near(got: Vec3, want: [f64; 3], what: &str) {
    let want = Vec3::new(want[0], want[1], want[2]);
    assert!(
        (got - want).max_abs() < 1e-12,
        "{what}: {got:?}, want {want:?}"
    );
}

/// A quarter turn about each axis moves the other two axes as the right-hand rule says, and
/// turns given together are taken about x first, then y, then z.
#[test]
fn rotations_turn_about_x_then_y_then_z() {
    let [x, y, z] = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    // About x: y → z, z → −y.
    let rx = rotation_xyz([90.0, 0.0, 0.0]);
    assert_near(turn(rx, x), [1.0, 0.0, 0.0], "x about x");
    assert_near(turn(rx, y), [0.0, 0.0, 1.0], "y about x");
    assert_near(turn(rx, z), [0.0, -1.0, 0.0], "z about x");
    // About y: z → x, x → −z.
    let ry = rotation_xyz([0.0, 90.0, 0.0]);
    assert_near(turn(ry, z), [1.0, 0.0, 0.0], "z about y");
    assert_near(turn(ry, x), [0.0, 0.0, -1.0], "x about y");
    // About z: x → y, y → −x.
    let rz = rotation_xyz([0.0, 0.0, 90.0]);
    assert_near(turn(rz, x), [0.0, 1.0, 0.0], "x about z");
    assert_near(turn(rz, y), [-1.0, 0.0, 0.0], "y about z");
    // x first: y → z (about x), then z → x (about y). Taken in the other order, y would stay
    // y about y and then go to z about x.
    assert_near(
        turn(rotation_xyz([90.0, 90.0, 0.0]), y),
        [1.0, 0.0, 0.0],
        "y, x then y",
    );
    // y first, then z: x → −z (about y), which z leaves alone; z first would give y, then y.
    assert_near(
        turn(rotation_xyz([0.0, 90.0, 90.0]), x),
        [0.0, 0.0, -1.0],
        "x, y then z",
    );
    // All three: z → −y (about x) → −y (about y) → x (about z).
    assert_near(
        turn(rotation_xyz([90.0, 90.0, 90.0]), z),
        [1.0, 0.0, 0.0],
        "z, x, y, z",
    );
}

/// A 2 × 1 × 1 m box of 3 × 2 × 2 points, its rest box's middle at (10, 0, 0), turned 90° about
/// x and then about z: each corner where the two quarter turns about the middle take it.
#[test]
fn a_scene_body_turns_about_its_middle_and_goes_to_its_centre() {
    let text = "[simulation]\ngravity = [0.0, 0.0, 0.0]\n\
                [box]\nmin = [-20.0, -20.0, -20.0]\nmax = [20.0, 20.0, 20.0]\n\
                [[body]]\ncube = { points = [3, 2, 2], size = [2.0, 1.0, 1.0] }\n\
                centre = [10.0, 0.0, 0.0]\nrotation = [90.0, 0.0, 90.0]\n";
    let scene = SceneFile::parse(text.as_bytes(), "s.toml")
        .unwrap()
        .to_scene("s.toml")
        .unwrap();
    let lattice = scene.model.body(0).lattice().clone();
    // By hand: a corner at d from the rest box's middle (1, 0.5, 0.5) goes to
    // (10, 0, 0) + Rz·Rx·d, with Rx (x, y, z) = (x, −z, y) and Rz (x, y, z) = (−y, x, z), so
    // Rz·Rx·d = (dz, dx, dy).
    for (ijk, want) in [
        ([0, 0, 0], [9.5, -1.0, -0.5]),  // d = (−1, −0.5, −0.5)
        ([2, 0, 0], [9.5, 1.0, -0.5]),   // d = (1, −0.5, −0.5)
        ([0, 1, 0], [9.5, -1.0, 0.5]),   // d = (−1, 0.5, −0.5)
        ([0, 0, 1], [10.5, -1.0, -0.5]), // d = (−1, −0.5, 0.5)
        ([1, 1, 1], [10.5, 0.0, 0.5]),   // d = (0, 0.5, 0.5)
    ] {
        let p = scene.state.pos[lattice.index(ijk[0], ijk[1], ijk[2])];
        assert_near(p, want, &format!("point {ijk:?}"));
    }
    // The middle of the turned box is the centre.
    let n = scene.state.pos.len() as f64;
    let mean = scene.state.pos.iter().fold(Vec3::ZERO, |a, &p| a + p) / n;
    assert_near(mean, [10.0, 0.0, 0.0], "middle");
}

/// A spin of 2 rad/s about z through the centre of mass, on top of a velocity of 0.1 m/s
/// along x: a corner 0.5 m from the middle in x and y moves at (0.1, 0, 0) + (0, 0, 2) × r.
#[test]
fn a_spun_body_moves_as_a_rigid_rotation_about_its_centre_of_mass() {
    let text = "[simulation]\ngravity = [0.0, 0.0, 0.0]\n\
                [[body]]\ncube = { points = [2, 2, 2], size = [1.0, 1.0, 1.0] }\n\
                centre = [0.5, -0.5, 0.0]\nvelocity = [0.1, 0.0, 0.0]\nspin = [0.0, 0.0, 2.0]\n";
    let scene = SceneFile::parse(text.as_bytes(), "s.toml")
        .unwrap()
        .to_scene("s.toml")
        .unwrap();
    let lattice = scene.model.body(0).lattice().clone();
    // ω × r = (−ω·ry, ω·rx, 0) for ω along z.
    for (ijk, want) in [
        ([0, 0, 0], [1.1, -1.0, 0.0]),  // r = (−0.5, −0.5, −0.5)
        ([1, 0, 0], [1.1, 1.0, 0.0]),   // r = (0.5, −0.5, −0.5)
        ([0, 1, 1], [-0.9, -1.0, 0.0]), // r = (−0.5, 0.5, 0.5)
        ([1, 1, 0], [-0.9, 1.0, 0.0]),  // r = (0.5, 0.5, −0.5)
    ] {
        let v = scene.state.vel[lattice.index(ijk[0], ijk[1], ijk[2])];
        assert_near(v, want, &format!("velocity of point {ijk:?}"));
    }
}
