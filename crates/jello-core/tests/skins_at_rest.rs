//! Bodies at rest on each other, measured as a user sees them: from their skins' triangles, not
//! from the contact model's own distance grids. A ball resting in a ring's hole presses the
//! ring's thin tube all around, which a distance grid four times as fine as the lattice rounds
//! by millimetres (see `contact_surface::REFINE`).

use jello_core::{Body, SceneFile, Scratch, TriMesh, Vec3};

/// The mesh `jello shape NAME --detail 6 --size 0.4` makes (as in `examples/pile.toml`).
fn small(name: &str) -> TriMesh {
    let mut mesh = TriMesh::shape(name, 6).expect("a shape");
    for v in &mut mesh.vertices {
        *v = *v * 0.4;
    }
    mesh
}

/// A scene body of `mesh` with 6 cells across, its box centred at `centre`.
fn mesh_body(name: &str, mesh: &TriMesh, centre: [f64; 3]) -> String {
    let vertices: Vec<[f64; 3]> = mesh.vertices.iter().map(|v| v.to_array()).collect();
    format!(
        "[[body]]\nname = \"{name}\"\ncentre = {centre:?}\ndensity = 1000.0\nmodulus = 200000.0\n\
         viscosity = 40.0\n[body.mesh]\ncells = 6\nvertices = {vertices:?}\ntriangles = {:?}\n",
        mesh.triangles
    )
}

/// The skin of `body` where its lattice points are `pos` (the model's), as triangles.
fn skin_triangles(body: &Body, pos: &[Vec3]) -> Vec<[Vec3; 3]> {
    let skin = body.skin.as_ref().expect("a mesh body");
    let mut vertices = vec![Vec3::ZERO; skin.len()];
    skin.positions(&pos[body.points()], &mut vertices);
    (skin.triangles.iter())
        .map(|t| t.map(|v| vertices[v as usize]))
        .collect()
}

/// The winding number of the closed triangles `mesh` about `p` (1 inside, 0 outside): the
/// triangles' solid angles (Van Oosterom and Strackee) over 4π.
fn winding(p: Vec3, mesh: &[[Vec3; 3]]) -> f64 {
    let angle: f64 = (mesh.iter())
        .map(|&[a, b, c]| {
            let (a, b, c) = (a - p, b - p, c - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let det = a.dot(b.cross(c));
            let div = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
            2.0 * det.atan2(div)
        })
        .sum();
    angle / (4.0 * std::f64::consts::PI)
}

/// The distance from `p` to the triangle `a b c`, by its closest point (Ericson, 5.1.5).
fn triangle_distance(p: Vec3, [a, b, c]: [Vec3; 3]) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * t)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

/// How deep the deepest vertex of either skin is inside the other (0 when none is).
fn overlap(one: &[[Vec3; 3]], other: &[[Vec3; 3]]) -> f64 {
    let deepest = |from: &[[Vec3; 3]], into: &[[Vec3; 3]]| {
        (from.iter().flatten())
            .filter(|&&p| winding(p, into) > 0.5)
            .map(|&p| {
                (into.iter())
                    .map(|&t| triangle_distance(p, t))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    };
    deepest(one, other).max(deepest(other, one))
}

/// A ball (0.4 m across, 6 cells) dropped 1 cm into the hole of a ring lying on the floor (0.4 m
/// across, its tube 0.12 m thick, 6 cells) comes to rest on the tube all around, and neither
/// skin is more than 0.5 % of a cell (0.33 mm) inside the other: 0.24 mm (0.36 %), where on grids
/// four times as fine as the lattices (both bodies') it was 0.53 mm (0.79 %).
#[test]
fn a_ball_resting_in_a_ring_stays_out_of_its_skin() {
    let (ring, ball) = (small("torus"), small("sphere"));
    // The ring's tube circle (radius 0.14 m, tube 0.06 m) on the floor at z = −1; the ball (0.2
    // m) touches it where its centre is 0.26 m from the circle.
    let floor = -1.0;
    let ring_z = floor + 0.06;
    let ball_z = ring_z + (0.26f64.powi(2) - 0.14f64.powi(2)).sqrt() + 0.01;
    let text = format!(
        "[simulation]\nintegrator = \"RK4\"\ndt = 0.0005\ngravity = [0.0, 0.0, -9.81]\n\
         [collision]\nstiffness = 500000.0\ndamping = 150.0\nfriction = 0.5\n\
         [box]\nmin = [-1.0, -1.0, {floor:?}]\nmax = [1.0, 1.0, 1.0]\n{}{}",
        mesh_body("ring", &ring, [0.0, 0.0, ring_z]),
        mesh_body("ball", &ball, [0.0, 0.0, ball_z]),
    );
    let scene = SceneFile::parse(text.as_bytes(), "ball-in-ring.toml")
        .unwrap()
        .to_scene("ball-in-ring.toml")
        .unwrap();
    let (model, mut state) = (scene.model, scene.state);
    let mut scratch = Scratch::new(&model);
    // 1.5 s: the ball settles in a few tenths of a second.
    for _ in 0..3000 {
        jello_core::step(
            &model,
            &mut state,
            &jello_core::Control::none(),
            &mut scratch,
        )
        .unwrap();
    }
    let bodies = model.bodies();
    let speed = (state.vel.iter()).fold(0.0f64, |m, v| m.max(v.length()));
    assert!(speed < 0.05, "still moving at {speed} m/s");
    let (ring_skin, ball_skin) = (
        skin_triangles(&bodies[0], &state.pos),
        skin_triangles(&bodies[1], &state.pos),
    );
    // Resting on the ring, not on the floor: the ball's lowest point is above it.
    let lowest = (ball_skin.iter().flatten()).fold(f64::INFINITY, |m, p| m.min(p.z));
    assert!(lowest > floor + 0.02, "the ball's bottom at {lowest} m");
    let cell = 0.4 / 6.0;
    let depth = overlap(&ring_skin, &ball_skin);
    eprintln!(
        "overlap {depth:.3e} m = {:.2} % of a cell",
        100.0 * depth / cell
    );
    assert!(
        depth < 0.005 * cell,
        "{depth} m deep: {:.2} % of a cell",
        100.0 * depth / cell
    );
}
