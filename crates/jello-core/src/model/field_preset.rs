//! The force fields `jello create --field` (and Python's `jello.create(field=…)`) sample onto a
//! grid: a uniform force, gravity, a vortex, a radial pull and a tornado, written as
//! `none | uniform:FX,FY,FZ | gravity[:G] | vortex:S[:x|y|z] | radial:S | tornado:S`.

use std::str::FromStr;

use crate::model::error::ModelError;
use crate::model::field::ForceField;
use crate::model::obstacle::Aabb;
use crate::vec3::Vec3;

/// Nodes per axis of the grid a preset is sampled on when none is given (`jello create
/// --resolution`, Python's `jello.create(resolution=…)`): the classic worlds' 30.
pub const DEFAULT_RESOLUTION: usize = 30;

/// `N` comma-separated finite numbers, e.g. `1,-2,0.5`.
pub fn parse_numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(format!(
            "expected {N} comma-separated numbers, found \"{s}\""
        ));
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("expected a finite number, found \"{p}\" in \"{s}\""))?;
    }
    Ok(out)
}

/// Axis of a vortex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Axis {
    /// x axis.
    X,
    /// y axis.
    Y,
    /// z axis.
    Z,
}

impl Axis {
    fn unit(self) -> Vec3 {
        match self {
            Axis::X => Vec3::new(1.0, 0.0, 0.0),
            Axis::Y => Vec3::new(0.0, 1.0, 0.0),
            Axis::Z => Vec3::new(0.0, 0.0, 1.0),
        }
    }
}

/// A force field to sample on the grid (forces in N at node position p).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FieldPreset {
    /// No field (`res` 0 in the file).
    None,
    /// The same force everywhere.
    Uniform(Vec3),
    /// Gravity of `g` m/s² along −z on each point: the force `(0, 0, −g·mass)`.
    Gravity(f64),
    /// Swirl about an axis through the origin: `s · (axis × p)`; the official rotate.w is
    /// `vortex:0.009765625` about z.
    Vortex(f64, Axis),
    /// Pull toward the centre of the box: `−s · p` (a negative s pushes out).
    Radial(f64),
    /// A vortex about z that sucks in near the floor and lifts near the axis:
    /// `s · ((−y, x, 0)/(r + 0.25) − 0.3 (x, y, 0) + (0, 0, 1.5 e^(−r²) − 0.5))`, `r = √(x² + y²)`.
    Tornado(f64),
}

impl FromStr for FieldPreset {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (kind, rest) = s.split_once(':').unwrap_or((s, ""));
        let number = |t: &str| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("expected a number after \"{kind}:\", found \"{t}\""))
        };
        match kind.to_ascii_lowercase().as_str() {
            "none" if rest.is_empty() => Ok(FieldPreset::None),
            "uniform" => Ok(FieldPreset::Uniform(Vec3::from_array(parse_numbers::<3>(rest)?))),
            "gravity" if rest.is_empty() => Ok(FieldPreset::Gravity(9.81)),
            "gravity" => Ok(FieldPreset::Gravity(number(rest)?)),
            "vortex" => {
                let (strength, axis) = rest.split_once(':').unwrap_or((rest, "z"));
                let axis = match axis.to_ascii_lowercase().as_str() {
                    "x" => Axis::X,
                    "y" => Axis::Y,
                    "z" => Axis::Z,
                    other => return Err(format!("expected a vortex axis x, y or z, found \"{other}\"")),
                };
                Ok(FieldPreset::Vortex(number(strength)?, axis))
            }
            "radial" => Ok(FieldPreset::Radial(number(rest)?)),
            "tornado" => Ok(FieldPreset::Tornado(number(rest)?)),
            _ => Err(format!(
                "expected none, uniform:FX,FY,FZ, gravity[:G], vortex:S[:AXIS], radial:S or tornado:S, found \"{s}\""
            )),
        }
    }
}

impl FieldPreset {
    /// The force at `p` of a field that does not depend on the mass (every one but gravity).
    pub fn force_on(self, p: Vec3) -> Vec3 {
        self.force(p, 0.0)
    }

    /// The force at `p` for points of mass `mass`.
    pub fn force(self, p: Vec3, mass: f64) -> Vec3 {
        match self {
            FieldPreset::None => Vec3::ZERO,
            FieldPreset::Uniform(f) => f,
            FieldPreset::Gravity(g) => Vec3::new(0.0, 0.0, -g * mass),
            FieldPreset::Vortex(s, axis) => axis.unit().cross(p) * s,
            FieldPreset::Radial(s) => p * -s,
            FieldPreset::Tornado(s) => {
                let r2 = p.x * p.x + p.y * p.y;
                let r = r2.sqrt();
                let swirl = Vec3::new(-p.y, p.x, 0.0) / (r + 0.25);
                let inward = Vec3::new(p.x, p.y, 0.0) * -0.3;
                let lift = Vec3::new(0.0, 0.0, 1.5 * (-r2).exp() - 0.5);
                (swirl + inward + lift) * s
            }
        }
    }

    /// The field sampled on a `res`³ grid over `bounds`, for points of mass `mass`; `None` for
    /// no field.
    pub fn sample(
        self,
        res: usize,
        bounds: Aabb,
        mass: f64,
    ) -> Result<Option<ForceField>, ModelError> {
        match self {
            FieldPreset::None => Ok(None),
            spec => ForceField::from_fn(res, bounds, |p| spec.force(p, mass)).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_as_the_command_line_spells_them() {
        let parse = |s: &str| s.parse::<FieldPreset>();
        assert_eq!(parse("none"), Ok(FieldPreset::None));
        assert_eq!(parse("gravity"), Ok(FieldPreset::Gravity(9.81)));
        assert_eq!(parse("Gravity:1.62"), Ok(FieldPreset::Gravity(1.62)));
        assert_eq!(parse("vortex:2:x"), Ok(FieldPreset::Vortex(2.0, Axis::X)));
        assert_eq!(parse("vortex:2"), Ok(FieldPreset::Vortex(2.0, Axis::Z)));
        assert_eq!(
            parse("uniform:1,-2,0.5"),
            Ok(FieldPreset::Uniform(Vec3::new(1.0, -2.0, 0.5)))
        );
        assert!(parse("vortex:2:w").unwrap_err().contains("axis x, y or z"));
        assert!(parse("radial:x").unwrap_err().contains("a number after"));
        assert!(parse("uniform:1,2")
            .unwrap_err()
            .contains("3 comma-separated"));
        assert!(parse("whirl").unwrap_err().starts_with("expected none"));
    }

    #[test]
    fn a_vortex_is_the_axis_cross_the_position_and_gravity_scales_with_mass() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(
            FieldPreset::Vortex(2.0, Axis::Z).force(p, 0.0),
            Vec3::new(-4.0, 2.0, 0.0)
        );
        assert_eq!(
            FieldPreset::Gravity(10.0).force(p, 0.5),
            Vec3::new(0.0, 0.0, -5.0)
        );
        let sampled = FieldPreset::Radial(2.0)
            .sample(2, Aabb::classic(), 1.0)
            .unwrap()
            .unwrap();
        // The grid's first node is the box's corner (−2, −2, −2): force −2·p.
        assert_eq!(sampled.forces()[0], Vec3::new(4.0, 4.0, 4.0));
        assert!(FieldPreset::None
            .sample(2, Aabb::classic(), 1.0)
            .unwrap()
            .is_none());
    }
}
