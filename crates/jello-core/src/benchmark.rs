//! The benchmark scene, built in code: what `jello bench`, the criterion benchmarks and the peer
//! implementations in `bench/peers` step.

use crate::model::field::ForceField;
use crate::model::integrator::Integrator;
use crate::model::lattice::Lattice;
use crate::model::{Aabb, Model, ModelBuilder, ModelError};
use crate::state::State;
use crate::vec3::Vec3;

/// The benchmark scene of `jello bench` (and of the peer implementations in `bench/peers`):
/// an `n × n × n` lattice of side 1 (spacing 1/(n−1)) centred in the box `[−2, 2]³`, kElastic 200,
/// dElastic 0.25, kCollision 400, dCollision 0.25, mass 1/512 per point at every `n`, every point
/// starting at velocity (10, −10, 20), gravity (0, 0, −9.81) as a uniform field of force
/// `mass·g`, no plane, dt 0.0005.
pub fn scene(n: usize, integrator: Integrator) -> Result<(Model, State), ModelError> {
    let mass = 1.0 / 512.0;
    let gravity = Vec3::new(0.0, 0.0, -9.81 * mass);
    let model = ModelBuilder::new()
        .lattice(Lattice::new([n, n, n], Vec3::new(1.0, 1.0, 1.0)))
        .elastic(200.0, 0.25)
        .collision(400.0, 0.25)
        .mass(mass)
        .field(Some(ForceField::from_fn(2, Aabb::classic(), |_| gravity)?))
        .dt(0.0005)
        .integrator(integrator)
        .build()?;
    let mut state = State::at_rest(&model);
    let centre = Vec3::new(0.5, 0.5, 0.5);
    state.pos.iter_mut().for_each(|p| *p -= centre);
    state
        .vel
        .iter_mut()
        .for_each(|v| *v = Vec3::new(10.0, -10.0, 20.0));
    Ok((model, state))
}

/// The frame-rate job of `jello bench --job` and `scripts/frame_rate.py` (whose Rapier runs do
/// the same): a 1 m cube of `n × n × n` points, 1 kg in all, of one material at every `n`
/// (modulus 1400 Pa and viscosity 1.75 N·s/m², so that the 8³ cube's springs have the classic
/// kElastic 200 N/m and dElastic 0.25 N·s/m), under gravity on the floor `z = 0` (a plane,
/// kCollision 400 N/m, dCollision 0.25 N·s/m, friction 0.5) in the box `[−2, 2]³`: resting on
/// it, or dropped with its bottom 0.5 m above it. It is the scene `jello create SCENE --cube N
/// --total-mass 1 --modulus 1400 --viscosity 1.75 --field gravity --plane 0,0,1,0 --at 0,0,C`
/// writes (C = 0.5 resting, 1 dropped).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    /// The cube resting on the floor.
    Rest,
    /// The cube dropped onto the floor from 0.5 m.
    Drop,
}

impl Job {
    /// The job's name (`rest`, `drop`).
    pub fn name(self) -> &'static str {
        match self {
            Job::Rest => "rest",
            Job::Drop => "drop",
        }
    }

    /// The job's scene file for a cube of `n³` points (RK4 at dt 0.0005 s, as `jello create`
    /// writes it).
    pub fn scene_text(self, n: usize) -> String {
        let centre = match self {
            Job::Rest => 0.5,
            Job::Drop => 1.0,
        };
        format!(
            r#"[simulation]
integrator = "RK4"
dt = 0.0005
steps_per_frame = 1
gravity = [0.0, 0.0, -9.81]

[collision]
stiffness = 400.0
damping = 0.25
friction = 0.5
wall_friction = 0.5

[box]
min = [-2.0, -2.0, -2.0]
max = [2.0, 2.0, 2.0]

[[obstacle]]
type = "plane"
coeffs = [0.0, 0.0, 1.0, 0.0]

[[body]]
name = "cube1"
centre = [0.0, 0.0, {centre:?}]
total_mass = 1.0
modulus = 1400.0
viscosity = 1.75

[body.cube]
points = [{n}, {n}, {n}]
size = [1.0, 1.0, 1.0]
"#
        )
    }

    /// The job's model and initial state for a cube of `n³` points stepped by `integrator` at
    /// `dt` (by default 1/60 s for an implicit integrator, 90 % of the stable step at rest for
    /// an explicit one, as the frame-rate table runs them).
    pub fn scene(
        self,
        n: usize,
        integrator: Integrator,
        dt: Option<f64>,
    ) -> Result<(Model, State), String> {
        let name = format!("the {n}³ {} job", self.name());
        let text = self.scene_text(n);
        let scene = crate::formats::scene::SceneFile::parse(text.as_bytes(), &name)
            .and_then(|file| file.to_scene(&name))
            .map_err(|e| e.to_string())?;
        let dt = match dt {
            Some(dt) => dt,
            None if integrator.is_implicit() => 1.0 / 60.0,
            None => {
                let stable = crate::integrate::stability::stable_dt(&scene.model, integrator);
                if stable.is_nan() || stable <= 0.0 {
                    return Err(format!(
                        "{name}: {integrator} has no stable step here; give one"
                    ));
                }
                0.9 * stable
            }
        };
        let model = (scene.model.to_builder())
            .integrator(integrator)
            .dt(dt)
            .build()
            .map_err(|e| format!("{name}: {e}"))?;
        Ok((model, scene.state))
    }

    /// The simulated time the job is measured over (s): 3 s up to 8³, 2 s up to 16³, 1 s
    /// beyond (long enough for the drop's impact at 0.32 s and the settling after it).
    pub fn simulated_time(n: usize) -> f64 {
        match n {
            0..=8 => 3.0,
            9..=16 => 2.0,
            _ => 1.0,
        }
    }
}
