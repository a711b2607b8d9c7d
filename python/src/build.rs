//! Building scenes in Python as `jello create OUT.toml` does: bodies (`cube`, `mesh`) with their
//! placement, motion, material, pins and regions; obstacles (`sphere`, `box`); then `create`
//! with the plane, gravity or field, walls, collision springs and time stepping. Each function
//! fills the scene file's own types (`jello_core::formats::scene`), so a built scene is exactly what
//! its saved `.toml` reads back as, and the core checks it as it checks a file.

use std::path::PathBuf;

use jello_core::formats::scene::{
    BodySpec, BoxSpec, CubeSpec, FieldSpec, MeshSpec, ObstacleSpec, PinSpec, RegionSpec, SceneFile,
    ShakeSpec, DEFAULT_CELLS,
};
use jello_core::{Aabb, FieldPreset, Integrator, Simulation as CoreSimulation, TriMesh};
use jello_io::Source;
use numpy::ndarray::Array2;
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::{numbers, vec3};
use crate::errors::{unreadable, world_error};
use crate::simulation::Simulation;

/// A body of a scene to be created: `jello.cube(...)` or `jello.mesh(...)`.
#[pyclass(module = "jello", frozen, from_py_object)]
#[derive(Clone)]
pub struct Body {
    pub(crate) spec: BodySpec,
}

#[pymethods]
impl Body {
    fn __repr__(&self) -> String {
        let shape = match (&self.spec.cube, &self.spec.mesh) {
            (Some(c), _) => format!("cube {:?} points, size {:?} m", c.points, c.size),
            (_, Some(m)) => format!("mesh of {} triangles, {} cells", m.triangles.len(), m.cells),
            _ => "no shape".into(),
        };
        match &self.spec.name {
            Some(n) => format!("Body({n:?}, {shape})"),
            None => format!("Body({shape})"),
        }
    }
}

/// A static obstacle: `jello.sphere(...)` or `jello.box(...)`.
#[pyclass(module = "jello", frozen, from_py_object)]
#[derive(Clone)]
pub struct Obstacle {
    pub(crate) spec: ObstacleSpec,
}

#[pymethods]
impl Obstacle {
    fn __repr__(&self) -> String {
        match &self.spec {
            ObstacleSpec::Sphere { centre, radius } => {
                format!("Obstacle(sphere at {centre:?}, radius {radius})")
            }
            ObstacleSpec::Box { min, max } => format!("Obstacle(box {min:?} to {max:?})"),
            ObstacleSpec::Plane { coeffs } => format!("Obstacle(plane {coeffs:?})"),
        }
    }
}

/// Points of a body held in place (or moved along a shake): `jello.pin(...)`.
#[pyclass(module = "jello", frozen, from_py_object)]
#[derive(Clone)]
pub struct Pin {
    pub(crate) spec: PinSpec,
}

#[pymethods]
impl Pin {
    fn __repr__(&self) -> String {
        format!("Pin(at={:?}, radius={})", self.spec.at, self.spec.radius)
    }
}

/// Springs of a body with their own stiffness, damping or rest length: `jello.region(...)`.
#[pyclass(module = "jello", frozen, from_py_object)]
#[derive(Clone)]
pub struct Region {
    pub(crate) spec: RegionSpec,
}

#[pymethods]
impl Region {
    fn __repr__(&self) -> String {
        let r = &self.spec;
        format!(
            "Region(min={:?}, max={:?}, stiffness={}, damping={}, rest={})",
            r.min, r.max, r.stiffness, r.damping, r.rest
        )
    }
}

/// A number or three (one per spring kind or per axis).
pub(crate) fn one_or_three(value: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    match value.extract::<f64>() {
        Ok(v) if v.is_finite() => Ok([v; 3]),
        Ok(v) => Err(PyValueError::new_err(format!(
            "{what}: expected a finite number, found {v}"
        ))),
        Err(_) => numbers::<3>(value, what),
    }
}

/// The settings every body takes, whatever its shape.
#[allow(clippy::too_many_arguments)]
fn common(
    spec: &mut BodySpec,
    (centre, at): (Option<&Bound<'_, PyAny>>, Option<&Bound<'_, PyAny>>),
    rotation: Option<&Bound<'_, PyAny>>,
    velocity: Option<&Bound<'_, PyAny>>,
    spin: Option<&Bound<'_, PyAny>>,
    mass: Option<f64>,
    total_mass: Option<f64>,
    density: Option<f64>,
    stiffness: Option<&Bound<'_, PyAny>>,
    damping: Option<&Bound<'_, PyAny>>,
    modulus: Option<f64>,
    viscosity: Option<f64>,
    pins: Vec<Pin>,
    regions: Vec<Region>,
    name: Option<String>,
) -> PyResult<()> {
    spec.centre = match (centre, at) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "give centre or at (the same: where the middle of the rest box goes), not both",
            ))
        }
        (Some(v), None) => Some(vec3(v, "centre")?),
        (None, Some(v)) => Some(vec3(v, "at")?),
        (None, None) => None,
    };
    spec.rotation = rotation.map(|v| vec3(v, "rotation")).transpose()?;
    spec.velocity = velocity.map(|v| vec3(v, "velocity")).transpose()?;
    spec.spin = spin.map(|v| vec3(v, "spin")).transpose()?;
    spec.mass = mass;
    spec.total_mass = total_mass;
    spec.density = density;
    spec.stiffness = stiffness
        .map(|v| one_or_three(v, "stiffness"))
        .transpose()?;
    spec.damping = damping.map(|v| one_or_three(v, "damping")).transpose()?;
    spec.modulus = modulus;
    spec.viscosity = viscosity;
    spec.pins = pins.into_iter().map(|p| p.spec).collect();
    spec.region = regions.into_iter().map(|r| r.spec).collect();
    if name.is_some() {
        spec.name = name;
    }
    spec.check().map_err(PyValueError::new_err)
}

/// Points per side of a `cube` when not given: the classic cube's 8.
const DEFAULT_CUBE_POINTS: usize = 8;

/// A body that is a box lattice of `n` points per side (or `(nx, ny, nz)`) and side `size` m
/// (or three sides); placement, motion and material as `jello create --cube` takes them:
/// `centre` (also `at`) is where the middle of its rest box goes (m), `rotation` degrees about x,
/// then y, then z, `velocity` (m/s), `spin` (rad/s about the centre of mass), `mass` per point,
/// `total_mass` or `density`, `stiffness` and `damping` per spring (one, or per kind) or
/// `modulus` and `viscosity` (docs/scenes.md, "One name per quantity").
#[pyfunction]
#[pyo3(signature = (
    n = None, size = None, *, centre = None, at = None, rotation = None, velocity = None, spin = None,
    mass = None, total_mass = None, density = None, stiffness = None, damping = None,
    modulus = None, viscosity = None, pins = Vec::new(), regions = Vec::new(), name = None
))]
#[allow(clippy::too_many_arguments)]
pub fn cube(
    n: Option<&Bound<'_, PyAny>>,
    size: Option<&Bound<'_, PyAny>>,
    centre: Option<&Bound<'_, PyAny>>,
    at: Option<&Bound<'_, PyAny>>,
    rotation: Option<&Bound<'_, PyAny>>,
    velocity: Option<&Bound<'_, PyAny>>,
    spin: Option<&Bound<'_, PyAny>>,
    mass: Option<f64>,
    total_mass: Option<f64>,
    density: Option<f64>,
    stiffness: Option<&Bound<'_, PyAny>>,
    damping: Option<&Bound<'_, PyAny>>,
    modulus: Option<f64>,
    viscosity: Option<f64>,
    pins: Vec<Pin>,
    regions: Vec<Region>,
    name: Option<String>,
) -> PyResult<Body> {
    let points: [usize; 3] = match n {
        None => [DEFAULT_CUBE_POINTS; 3],
        Some(n) => match n.extract::<usize>() {
            Ok(k) => [k; 3],
            Err(_) => n.extract::<[usize; 3]>().map_err(|_| {
                PyValueError::new_err("n: expected points per side (an int ≥ 2) or three of them")
            })?,
        },
    };
    let size = match size {
        Some(s) => one_or_three(s, "size")?,
        None => [1.0; 3],
    };
    let mut spec = BodySpec {
        cube: Some(CubeSpec { points, size }),
        ..BodySpec::default()
    };
    common(
        &mut spec,
        (centre, at),
        rotation,
        velocity,
        spin,
        mass,
        total_mass,
        density,
        stiffness,
        damping,
        modulus,
        viscosity,
        pins,
        regions,
        name,
    )?;
    Ok(Body { spec })
}

/// A body voxelised from a closed mesh into `cells` cells along its longest side: read from
/// `path` (OBJ, or STL in ASCII or binary), or given as `vertices` `(m, 3)` and `triangles`
/// `(t, 3)` arrays. Otherwise as `cube`.
#[pyfunction]
#[pyo3(signature = (
    path = None, *, vertices = None, triangles = None, cells = DEFAULT_CELLS, centre = None, at = None,
    rotation = None, velocity = None, spin = None, mass = None, total_mass = None,
    density = None, stiffness = None, damping = None, modulus = None, viscosity = None,
    pins = Vec::new(), regions = Vec::new(), name = None
))]
#[allow(clippy::too_many_arguments)]
pub fn mesh(
    py: Python<'_>,
    path: Option<PathBuf>,
    vertices: Option<&Bound<'_, PyAny>>,
    triangles: Option<&Bound<'_, PyAny>>,
    cells: usize,
    centre: Option<&Bound<'_, PyAny>>,
    at: Option<&Bound<'_, PyAny>>,
    rotation: Option<&Bound<'_, PyAny>>,
    velocity: Option<&Bound<'_, PyAny>>,
    spin: Option<&Bound<'_, PyAny>>,
    mass: Option<f64>,
    total_mass: Option<f64>,
    density: Option<f64>,
    stiffness: Option<&Bound<'_, PyAny>>,
    damping: Option<&Bound<'_, PyAny>>,
    modulus: Option<f64>,
    viscosity: Option<f64>,
    pins: Vec<Pin>,
    regions: Vec<Region>,
    name: Option<String>,
) -> PyResult<Body> {
    let (vertices, triangles, stem) = match (path, vertices, triangles) {
        (Some(p), None, None) => {
            let m = read(py, &p)?;
            let stem = p
                .file_stem()
                .map_or("mesh".into(), |s| s.to_string_lossy().into_owned());
            (
                m.vertices.iter().map(|v| v.to_array()).collect(),
                m.triangles,
                stem,
            )
        }
        (None, Some(v), Some(t)) => {
            let vertices = crate::arrays::from_array(v, v.len()?, "vertices")?;
            let triangles = triangle_array(t)?;
            (
                vertices.iter().map(|v| v.to_array()).collect(),
                triangles,
                "mesh".to_string(),
            )
        }
        _ => {
            return Err(PyValueError::new_err(
                "give a mesh file's path, or vertices and triangles arrays, not both",
            ))
        }
    };
    let mut spec = BodySpec {
        mesh: Some(MeshSpec {
            cells,
            vertices,
            triangles,
        }),
        name: Some(stem),
        ..BodySpec::default()
    };
    common(
        &mut spec,
        (centre, at),
        rotation,
        velocity,
        spin,
        mass,
        total_mass,
        density,
        stiffness,
        damping,
        modulus,
        viscosity,
        pins,
        regions,
        name,
    )?;
    Ok(Body { spec })
}

/// A `(t, 3)` array of vertex indices.
fn triangle_array(value: &Bound<'_, PyAny>) -> PyResult<Vec<[u32; 3]>> {
    let rows: Vec<Vec<i64>> = value.extract().or_else(|_| {
        value
            .call_method0("tolist")
            .and_then(|l| l.extract())
            .map_err(|_| {
                PyValueError::new_err("triangles: expected a (t, 3) array of vertex indices")
            })
    })?;
    rows.iter()
        .enumerate()
        .map(|(i, r)| match r.as_slice() {
            [a, b, c] => {
                let index = |v: i64| {
                    u32::try_from(v).map_err(|_| {
                        PyValueError::new_err(format!(
                            "triangles: row {i} has the index {v}, expected 0 or more"
                        ))
                    })
                };
                Ok([index(*a)?, index(*b)?, index(*c)?])
            }
            _ => Err(PyValueError::new_err(format!(
                "triangles: row {i} has {} indices, expected 3",
                r.len()
            ))),
        })
        .collect()
}

/// A mesh file read and checked (closed, consistently wound); errors as `jello.WorldError`
/// naming the file and line.
fn read(py: Python<'_>, path: &std::path::Path) -> PyResult<TriMesh> {
    if let Some(err) = unreadable(path) {
        return Err(err);
    }
    let name = path.display().to_string();
    let bytes =
        jello_io::read_bounded(path).map_err(|e| world_error(py, e.message, Some(&name)))?;
    TriMesh::parse(&bytes, &name).map_err(|e| world_error(py, e.to_string(), Some(&name)))
}

/// The vertices `(m, 3)` float64 and triangles `(t, 3)` uint32 of a mesh file (OBJ, or STL in
/// ASCII or binary), as Jello reads it.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub fn read_mesh<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>)> {
    let m = read(py, &path)?;
    let vertices = crate::arrays::to_array(py, &m.vertices);
    let flat: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    let triangles = Array2::from_shape_vec((m.triangles.len(), 3), flat)
        .expect("three indices per triangle make a (t, 3) array");
    Ok((vertices, PyArray2::from_owned_array(py, triangles)))
}

/// A solid ball obstacle.
#[pyfunction]
pub fn sphere(centre: &Bound<'_, PyAny>, radius: f64) -> PyResult<Obstacle> {
    Ok(Obstacle {
        spec: ObstacleSpec::Sphere {
            centre: vec3(centre, "centre")?,
            radius,
        },
    })
}

/// A solid axis-aligned box obstacle from `min` to `max` (m).
#[pyfunction]
#[pyo3(name = "box")]
pub fn solid_box(min: &Bound<'_, PyAny>, max: &Bound<'_, PyAny>) -> PyResult<Obstacle> {
    Ok(Obstacle {
        spec: ObstacleSpec::Box {
            min: vec3(min, "min")?,
            max: vec3(max, "max")?,
        },
    })
}

/// Pins a body's points within `radius` m of `at` (at rest, after placing the body); radius 0
/// pins the nearest point. `shake=(amplitude (ax, ay, az) m, frequency Hz)` moves them by
/// amplitude · sin(2π f t).
#[pyfunction]
#[pyo3(signature = (at, radius = 0.0, *, shake = None))]
pub fn pin(
    at: &Bound<'_, PyAny>,
    radius: f64,
    shake: Option<(Bound<'_, PyAny>, f64)>,
) -> PyResult<Pin> {
    if !(radius.is_finite() && radius >= 0.0) {
        return Err(PyValueError::new_err(format!(
            "radius: expected a radius ≥ 0 (m), found {radius}"
        )));
    }
    let shake = shake
        .map(|(amplitude, frequency)| {
            Ok::<_, PyErr>(ShakeSpec {
                amplitude: vec3(&amplitude, "shake amplitude")?,
                frequency,
            })
        })
        .transpose()?;
    Ok(Pin {
        spec: PinSpec {
            at: vec3(at, "at")?,
            radius,
            shake,
            path: None,
        },
    })
}

/// The springs with both ends in the box `min`–`max` (at rest, after placing the body) get
/// these factors on their stiffness, damping and rest length (overlapping regions multiply).
#[pyfunction]
#[pyo3(signature = (min, max, *, stiffness = 1.0, damping = 1.0, rest = 1.0))]
pub fn region(
    min: &Bound<'_, PyAny>,
    max: &Bound<'_, PyAny>,
    stiffness: f64,
    damping: f64,
    rest: f64,
) -> PyResult<Region> {
    let spec = RegionSpec {
        min: vec3(min, "min")?,
        max: vec3(max, "max")?,
        stiffness,
        damping,
        rest,
    };
    spec.scale()
        .check()
        .map_err(|e| PyValueError::new_err(format!("region: {e}")))?;
    Ok(Region { spec })
}

/// A scene of `bodies` (and `obstacles`) made into a simulation, as `jello create OUT.toml`
/// makes one: `plane=(a, b, c, d)` keeps the bodies on the first body's side of
/// `a x + b y + c z + d = 0`; `gravity` (m/s², default (0, 0, −9.81)) or a `field`: a preset
/// ("uniform:FX,FY,FZ", "gravity[:G]", "vortex:S[:x|y|z]", "radial:S", "tornado:S", sampled on
/// a `resolution`³ grid, default 30; also `res`) or forces (N) as a `(r, r, r, 3)` array over
/// the walls; a field replaces the
/// default gravity. `bounds=(min, max)` are the walls (default ±2 m); `friction` is the Coulomb
/// coefficient of obstacles and contacts, `wall_friction` of the walls and the plane (0.5 each by
/// default); `self_contact=True` lets each body's surface touch its own (off by default).
#[pyfunction]
#[pyo3(signature = (
    bodies, *, obstacles = Vec::new(), plane = None, gravity = None, field = None,
    resolution = None, res = None, bounds = None, collision_stiffness = None, collision_damping = None, friction = None,
    wall_friction = None, self_contact = false,
    integrator = "RK4", dt = None, steps_per_frame = None, name = "<scene>"
))]
#[allow(clippy::too_many_arguments)]
pub fn create(
    py: Python<'_>,
    bodies: Vec<Body>,
    obstacles: Vec<Obstacle>,
    plane: Option<&Bound<'_, PyAny>>,
    gravity: Option<&Bound<'_, PyAny>>,
    field: Option<&Bound<'_, PyAny>>,
    resolution: Option<usize>,
    res: Option<usize>,
    bounds: Option<(Bound<'_, PyAny>, Bound<'_, PyAny>)>,
    collision_stiffness: Option<f64>,
    collision_damping: Option<f64>,
    friction: Option<f64>,
    wall_friction: Option<f64>,
    self_contact: bool,
    integrator: &str,
    dt: Option<f64>,
    steps_per_frame: Option<u32>,
    name: &str,
) -> PyResult<Simulation> {
    if bodies.is_empty() {
        return Err(PyValueError::new_err(
            "bodies: a scene needs at least one body (jello.cube(...) or jello.mesh(...))",
        ));
    }
    let res = match (resolution, res) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "give resolution or res (the same: the field's nodes per axis), not both",
            ))
        }
        (r, s) => r
            .or(s)
            .unwrap_or(jello_core::model::field_preset::DEFAULT_RESOLUTION),
    };
    let integrator = integrator
        .parse::<Integrator>()
        .map_err(|e| PyValueError::new_err(format!("integrator: {e}")))?;
    // Unnamed cubes are named as `jello create --cube` names them.
    let specs = bodies
        .into_iter()
        .enumerate()
        .map(|(b, body)| {
            let mut spec = body.spec;
            if spec.name.is_none() && spec.cube.is_some() {
                spec.name = Some(format!("cube{}", b + 1));
            }
            spec
        })
        .collect();
    let mut scene = SceneFile::new(specs);
    scene.simulation.integrator = integrator.name().to_string();
    if let Some(dt) = dt {
        scene.simulation.dt = dt;
    }
    if let Some(n) = steps_per_frame {
        scene.simulation.steps_per_frame = n;
    }
    if let Some(k) = collision_stiffness {
        scene.collision.stiffness = k;
    }
    if let Some(d) = collision_damping {
        scene.collision.damping = d;
    }
    if let Some(f) = friction {
        scene.collision.friction = f;
    }
    if let Some(f) = wall_friction {
        scene.collision.wall_friction = f;
    }
    scene.collision.self_contact = self_contact;
    // The walls are written out even when they are the default, as `jello create` does.
    let classic = Aabb::classic();
    scene.bounds = Some(match bounds {
        Some((min, max)) => BoxSpec {
            min: vec3(&min, "bounds min")?,
            max: vec3(&max, "bounds max")?,
        },
        None => BoxSpec {
            min: classic.min.to_array(),
            max: classic.max.to_array(),
        },
    });
    let gravity = gravity.map(|g| vec3(g, "gravity")).transpose()?;
    match field {
        None => scene
            .set_gravity_and_field(FieldPreset::None, res, gravity)
            .map_err(PyValueError::new_err)?,
        Some(f) => match f.extract::<String>() {
            Ok(text) => {
                let preset = text
                    .parse::<FieldPreset>()
                    .map_err(|e| PyValueError::new_err(format!("field: {e}")))?;
                scene
                    .set_gravity_and_field(preset, res, gravity)
                    .map_err(PyValueError::new_err)?;
            }
            Err(_) => {
                scene.simulation.gravity = Some(gravity.unwrap_or([0.0; 3]));
                scene.field = Some(field_array(f)?);
            }
        },
    }
    scene.obstacles = obstacles.into_iter().map(|o| o.spec).collect();
    if let Some(p) = plane {
        let coeffs = numbers::<4>(p, "plane")?;
        scene
            .add_plane_facing_first_body(coeffs, name)
            .map_err(|e| world_error(py, e.to_string(), None))?;
    }
    let made = scene
        .to_scene(name)
        .map_err(|e| world_error(py, e.to_string(), None))?;
    let sim = CoreSimulation::new(made.model, made.state);
    Ok(Simulation::new(sim, Source::Scene(scene), name.to_string()))
}

/// Forces (N) on a grid as an `(r, r, r, 3)` array, x slowest, as a scene's `[field]`.
fn field_array(value: &Bound<'_, PyAny>) -> PyResult<FieldSpec> {
    let numpy = value.py().import("numpy")?;
    let array = numpy
        .call_method1("asarray", (value, "float64"))
        .map_err(|_| {
            PyValueError::new_err(
                "field: expected a preset name or an (r, r, r, 3) array of forces",
            )
        })?;
    let array = array
        .cast_into::<numpy::PyArrayDyn<f64>>()
        .map_err(|_| PyValueError::new_err("field: expected an (r, r, r, 3) array of forces"))?;
    let shape = array.shape().to_vec();
    let r = shape.first().copied().unwrap_or(0);
    if shape.len() != 4 || shape[1] != r || shape[2] != r || shape[3] != 3 {
        return Err(PyValueError::new_err(format!(
            "field: expected an (r, r, r, 3) array of forces, found shape {shape:?}"
        )));
    }
    let readonly = array.readonly();
    let flat: Vec<f64> = readonly.as_array().iter().copied().collect();
    Ok(FieldSpec {
        resolution: r,
        forces: flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    })
}
