//! The classic world file (`.w`): reader and writer.
//!
//! The format (docs/spec.md) is whitespace-separated text in which line breaks carry no meaning:
//! integrator; `dt n`; `kElastic dElastic kCollision dCollision`; `mass`; `incPlanePresent` and,
//! only when it is 1, `a b c d`; `res` and `res³` force triples; 512 position triples; 512
//! velocity triples. The reader is stricter than the original one: it checks every value and
//! rejects trailing data. Errors name the source, the line and what was expected.
//!
//! The writer prints each number in the shortest form that reads back to the same double, so a
//! saved state continues bit for bit.

use std::fmt::{self, Write as _};

use crate::diagnostics::centre_of_mass;
use crate::model::field::{ForceField, RES_RANGE};
use crate::model::integrator::Integrator;
use crate::model::lattice::Lattice;
use crate::model::{Aabb, Model, ModelBuilder, ModelError, Plane};
use crate::state::State;
use crate::vec3::Vec3;

/// Numbers shown to a few digits (in `vec3`, the bottom layer, so that messages there use it).
pub use crate::vec3::significant;

/// Points in a world file: the classic 8×8×8 lattice.
pub const POINTS: usize = 512;

/// The contents of a world file.
#[derive(Clone, Debug, PartialEq)]
pub struct World {
    /// The integrator named in the file (or the override given to the reader).
    pub integrator: Integrator,
    /// Time step (s).
    pub dt: f64,
    /// Simulation steps per displayed frame.
    pub steps_per_frame: u32,
    /// Stiffness of every lattice spring (N/m).
    pub k_elastic: f64,
    /// Damping of every lattice spring (N·s/m).
    pub d_elastic: f64,
    /// Stiffness of the collision springs (N/m).
    pub k_collision: f64,
    /// Damping of the collision springs (N·s/m).
    pub d_collision: f64,
    /// Mass of each point (kg).
    pub mass: f64,
    /// Inclined plane `[a, b, c, d]`, when present.
    pub plane: Option<[f64; 4]>,
    /// Force field: resolution and `res³` forces (N), when present.
    pub field: Option<(usize, Vec<Vec3>)>,
    /// 512 positions (m), flat lattice index.
    pub positions: Vec<Vec3>,
    /// 512 velocities (m/s), flat lattice index.
    pub velocities: Vec<Vec3>,
}

/// A world file that could not be read: where, and what was expected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldError {
    /// The file name (or other label) the text came from.
    pub source_name: String,
    /// 1-based line of the offending token; 0 when the error is about the whole file.
    pub line: usize,
    /// What was expected and what was found.
    pub message: String,
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: {}", self.source_name, self.line, self.message)
        } else {
            write!(f, "{}: {}", self.source_name, self.message)
        }
    }
}

impl std::error::Error for WorldError {}

/// How the reader treats the integrator word.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions {
    /// Use this integrator whatever the file names (the file's word must still be a word). This
    /// lets a file with an unknown integrator run.
    pub integrator: Option<Integrator>,
}

/// A whitespace-separated token and the line it starts on.
pub(crate) struct Token<'a> {
    pub(crate) text: &'a [u8],
    pub(crate) line: usize,
}

/// C's `isspace`: the bytes that separate tokens.
pub(crate) fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
}

/// Splits text on C's `isspace` bytes, counting lines (the mesh readers share it).
pub(crate) struct Tokens<'a> {
    bytes: &'a [u8],
    at: usize,
    /// The 1-based line the cursor is on.
    pub(crate) line: usize,
}

impl<'a> Tokens<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Tokens {
            bytes,
            at: 0,
            line: 1,
        }
    }

    pub(crate) fn next_token(&mut self) -> Option<Token<'a>> {
        while self.at < self.bytes.len() && is_space(self.bytes[self.at]) {
            if self.bytes[self.at] == b'\n' {
                self.line += 1;
            }
            self.at += 1;
        }
        if self.at == self.bytes.len() {
            return None;
        }
        let start = self.at;
        while self.at < self.bytes.len() && !is_space(self.bytes[self.at]) {
            self.at += 1;
        }
        Some(Token {
            text: &self.bytes[start..self.at],
            line: self.line,
        })
    }

    /// Skips the rest of the current line, its line break included.
    pub(crate) fn skip_line(&mut self) {
        match self.bytes[self.at..].iter().position(|&b| b == b'\n') {
            Some(n) => {
                self.at += n + 1;
                self.line += 1;
            }
            None => self.at = self.bytes.len(),
        }
    }
}

/// A token as shown in an error: printable, quoted, at most 32 characters.
pub(crate) fn show(token: &[u8]) -> String {
    const MAX: usize = 32;
    let cut = &token[..token.len().min(MAX)];
    let mut s = format!("\"{}\"", cut.escape_ascii());
    if token.len() > MAX {
        s.insert(s.len() - 1, '…');
    }
    s
}

/// The reader's cursor: tokens plus the source name for errors.
struct Reader<'a> {
    tokens: Tokens<'a>,
    source: &'a str,
}

impl<'a> Reader<'a> {
    fn error(&self, line: usize, message: String) -> WorldError {
        WorldError {
            source_name: self.source.to_string(),
            line,
            message,
        }
    }

    /// The next token, or an error saying the file ended where `what` was expected.
    fn expect(&mut self, what: &dyn Fn() -> String) -> Result<Token<'a>, WorldError> {
        match self.tokens.next_token() {
            Some(t) => Ok(t),
            None => Err(self.error(
                self.tokens.line,
                format!("expected {}, but the file ends here", what()),
            )),
        }
    }

    /// A finite number; `what` describes it for an error and is called only then (a file holds
    /// up to 84 000 numbers).
    fn number_lazy(&mut self, what: &dyn Fn() -> String) -> Result<(f64, usize), WorldError> {
        let t = self.expect(what)?;
        let value = std::str::from_utf8(t.text)
            .ok()
            .and_then(|s| s.parse::<f64>().ok());
        match value {
            Some(v) if v.is_finite() => Ok((v, t.line)),
            Some(_) => Err(self.error(
                t.line,
                format!(
                    "expected {}, found {}, which is not a finite number",
                    what(),
                    show(t.text)
                ),
            )),
            None => Err(self.error(
                t.line,
                format!("expected {}, found {}", what(), show(t.text)),
            )),
        }
    }

    /// A finite number.
    fn number(&mut self, what: &str) -> Result<(f64, usize), WorldError> {
        self.number_lazy(&|| what.to_string())
    }

    /// A number that must satisfy `ok`, described by `rule` in the error.
    fn number_where(
        &mut self,
        what: &str,
        rule: &str,
        ok: impl Fn(f64) -> bool,
    ) -> Result<f64, WorldError> {
        let (v, line) = self.number(what)?;
        if ok(v) {
            Ok(v)
        } else {
            Err(self.error(line, format!("expected {what} ({rule}), found {v}")))
        }
    }

    /// A decimal integer.
    fn integer(&mut self, what: &str) -> Result<(i64, usize), WorldError> {
        let t = self.expect(&|| what.to_string())?;
        match std::str::from_utf8(t.text)
            .ok()
            .and_then(|s| s.parse::<i64>().ok())
        {
            Some(v) => Ok((v, t.line)),
            None => Err(self.error(t.line, format!("expected {what}, found {}", show(t.text)))),
        }
    }

    /// Three numbers; `what` describes the triple for an error.
    fn vec3(&mut self, what: &dyn Fn() -> String) -> Result<Vec3, WorldError> {
        let (x, _) = self.number_lazy(&|| format!("{}, x", what()))?;
        let (y, _) = self.number_lazy(&|| format!("{}, y", what()))?;
        let (z, _) = self.number_lazy(&|| format!("{}, z", what()))?;
        Ok(Vec3::new(x, y, z))
    }
}

/// `(i, j, k)` of flat index `n` in a cube of side `side`.
fn ijk(n: usize, side: usize) -> (usize, usize, usize) {
    (n / (side * side), (n / side) % side, n % side)
}

impl World {
    /// Reads a world from the bytes of a file; `source_name` labels errors (usually the path).
    pub fn parse(
        bytes: &[u8],
        source_name: &str,
        options: ReadOptions,
    ) -> Result<World, WorldError> {
        let mut r = Reader {
            tokens: Tokens::new(bytes),
            source: source_name,
        };
        if bytes.is_empty() {
            return Err(r.error(1, "the file is empty; expected a world file".into()));
        }

        // 1. Integrator.
        let what = "an integrator name (Euler, RK2, RK4, ...)";
        let t = r.expect(&|| what.to_string())?;
        let word = std::str::from_utf8(t.text)
            .ok()
            .filter(|w| w.bytes().all(|b| b.is_ascii_graphic()) && w.parse::<f64>().is_err());
        let Some(word) = word else {
            return Err(r.error(t.line, format!("expected {what}, found {}", show(t.text))));
        };
        let integrator = match options.integrator {
            Some(i) => i,
            None => word
                .parse::<Integrator>()
                .map_err(|e| r.error(t.line, e.to_string()))?,
        };

        // 2. Time step and steps per frame.
        let dt = r.number_where("the time step dt", "finite and positive", |v| v > 0.0)?;
        let (n, line) = r.integer("the steps per frame n (an integer ≥ 1)")?;
        let steps_per_frame = u32::try_from(n).ok().filter(|&n| n >= 1).ok_or_else(|| {
            r.error(
                line,
                format!("expected the steps per frame n (at least 1), found {n}"),
            )
        })?;

        // 3. Springs, 4. mass.
        let k_elastic = r.number_where("kElastic", "positive", |v| v > 0.0)?;
        let d_elastic = r.number_where("dElastic", "at least 0", |v| v >= 0.0)?;
        let k_collision = r.number_where("kCollision", "positive", |v| v > 0.0)?;
        let d_collision = r.number_where("dCollision", "at least 0", |v| v >= 0.0)?;
        let mass = r.number_where("the mass of a point", "positive", |v| v > 0.0)?;

        // 5. Inclined plane.
        let (present, line) = r.integer("incPlanePresent (0 or 1)")?;
        let plane = match present {
            0 => None,
            1 => {
                let (a, line) = r.number("plane coefficient a")?;
                let (b, _) = r.number("plane coefficient b")?;
                let (c, _) = r.number("plane coefficient c")?;
                let (d, _) = r.number("plane coefficient d")?;
                // The depth divides by |(a, b, c)|: it must be a finite, non-zero number.
                let norm = Vec3::new(a, b, c).length();
                if !(norm.is_finite() && norm > 0.0) {
                    return Err(r.error(
                        line,
                        format!(
                            "expected a plane normal (a, b, c) of finite, non-zero length, \
                             found ({a}, {b}, {c}) of length {norm}"
                        ),
                    ));
                }
                Some([a, b, c, d])
            }
            other => {
                return Err(r.error(
                    line,
                    format!("expected incPlanePresent (0 or 1), found {other}"),
                ))
            }
        };

        // 6. Force field: check the resolution before allocating anything for it.
        let (res, line) = r.integer("the force field resolution (0, or 2 to 30)")?;
        let field = match res {
            0 => None,
            res if res >= *RES_RANGE.start() as i64 && res <= *RES_RANGE.end() as i64 => {
                let res = res as usize;
                let count = res * res * res;
                let mut forces = Vec::with_capacity(count);
                for n in 0..count {
                    let (i, j, k) = ijk(n, res);
                    forces.push(r.vec3(&|| format!("force field node ({i}, {j}, {k}) of {res}³"))?);
                }
                Some((res, forces))
            }
            other => {
                return Err(r.error(
                    line,
                    format!("expected the force field resolution (0, or 2 to 30), found {other}"),
                ))
            }
        };

        // 7, 8. Positions and velocities.
        let mut positions = Vec::with_capacity(POINTS);
        for n in 0..POINTS {
            let (i, j, k) = ijk(n, 8);
            positions.push(r.vec3(&|| format!("the position of point ({i}, {j}, {k}) of 512"))?);
        }
        let mut velocities = Vec::with_capacity(POINTS);
        for n in 0..POINTS {
            let (i, j, k) = ijk(n, 8);
            velocities.push(r.vec3(&|| format!("the velocity of point ({i}, {j}, {k}) of 512"))?);
        }

        // Nothing but whitespace may follow.
        if let Some(t) = r.tokens.next_token() {
            return Err(r.error(
                t.line,
                format!(
                    "expected the end of the file after the 512 velocities, found {}",
                    show(t.text)
                ),
            ));
        }

        Ok(World {
            integrator,
            dt,
            steps_per_frame,
            k_elastic,
            d_elastic,
            k_collision,
            d_collision,
            mass,
            plane,
            field,
            positions,
            velocities,
        })
    }

    /// The world as file text, every number in shortest round-trip form.
    pub fn to_text(&self) -> String {
        let mut s =
            String::with_capacity(64 * (2 * POINTS + self.field.as_ref().map_or(0, |f| f.1.len())));
        let triple = |s: &mut String, v: &Vec3| {
            let _ = writeln!(s, "{} {} {}", Num(v.x), Num(v.y), Num(v.z));
        };
        let _ = writeln!(s, "{}", self.integrator.name());
        let _ = writeln!(s, "{} {}", Num(self.dt), self.steps_per_frame);
        let _ = writeln!(
            s,
            "{} {} {} {}",
            Num(self.k_elastic),
            Num(self.d_elastic),
            Num(self.k_collision),
            Num(self.d_collision)
        );
        let _ = writeln!(s, "{}", Num(self.mass));
        match self.plane {
            Some([a, b, c, d]) => {
                let _ = writeln!(s, "1\n{} {} {} {}", Num(a), Num(b), Num(c), Num(d));
            }
            None => s.push_str("0\n"),
        }
        match &self.field {
            Some((res, forces)) => {
                let _ = writeln!(s, "{res}");
                forces.iter().for_each(|f| triple(&mut s, f));
            }
            None => s.push_str("0\n"),
        }
        self.positions.iter().for_each(|p| triple(&mut s, p));
        self.velocities.iter().for_each(|v| triple(&mut s, v));
        s
    }

    /// The model and initial state this world describes. The plane's allowed side is the side
    /// holding the centre of mass of the positions.
    pub fn to_simulation(&self) -> Result<(Model, State), ModelError> {
        let plane = match self.plane {
            Some(coeffs) => Some(Plane::facing(coeffs, centre_of_mass(&self.positions))?),
            None => None,
        };
        let field = match &self.field {
            Some((res, forces)) => Some(ForceField::new(*res, Aabb::classic(), forces.clone())?),
            None => None,
        };
        let model = ModelBuilder::new()
            .lattice(Lattice::classic())
            .integrator(self.integrator)
            .dt(self.dt)
            .steps_per_frame(self.steps_per_frame)
            .elastic(self.k_elastic, self.d_elastic)
            .collision(self.k_collision, self.d_collision)
            .mass(self.mass)
            .plane(plane)
            .field(field)
            .build()?;
        let state = State::new(self.positions.clone(), self.velocities.clone());
        Ok((model, state))
    }

    /// The world file that holds `model` with `state` as its initial condition. Fails for what the
    /// format cannot say: a lattice other than the classic cube, per-kind springs, another box.
    pub fn from_simulation(model: &Model, state: &State) -> Result<World, ModelError> {
        let [body] = model.bodies() else {
            return Err(ModelError::new("a world file holds one body only"));
        };
        if !(body.is_full()
            && body.lattice().is_classic()
            && body.origin == Vec3::ZERO
            && body.rotation == crate::model::body::IDENTITY)
        {
            return Err(ModelError::new(
                "a world file holds the classic 8×8×8 cube of side 1 only",
            ));
        }
        if body.spring_table().is_some() {
            return Err(ModelError::new(
                "a world file holds no per-spring rest lengths, stiffnesses or dampings",
            ));
        }
        let m = &body.material;
        if !(m.stiffness.iter().all(|&k| k == m.stiffness[0])
            && m.damping.iter().all(|&d| d == m.damping[0]))
        {
            return Err(ModelError::new(
                "a world file holds one stiffness and one damping for all springs",
            ));
        }
        if model.bounds != Aabb::classic() {
            return Err(ModelError::new("a world file holds the box [-2, 2]³ only"));
        }
        if model.gravity != Vec3::ZERO {
            return Err(ModelError::new(
                "a world file holds no gravity besides its force field",
            ));
        }
        if !model.pins.is_empty() {
            return Err(ModelError::new("a world file holds no pinned points"));
        }
        if !model.obstacles.is_empty() {
            return Err(ModelError::new(
                "a world file holds no obstacles besides the box and the inclined plane",
            ));
        }
        if let Some(p) = state.pos.iter().chain(&state.vel).find(|v| !v.is_finite()) {
            return Err(ModelError::new(format!(
                "refusing to save a non-finite state ({p})"
            )));
        }
        Ok(World {
            integrator: model.integrator,
            dt: model.dt,
            steps_per_frame: model.steps_per_frame,
            k_elastic: m.stiffness[0],
            d_elastic: m.damping[0],
            k_collision: model.k_collision,
            d_collision: model.d_collision,
            mass: m.mass,
            plane: model.plane.map(|p| p.coeffs),
            field: model.field.as_ref().map(|f| (f.res(), f.forces().to_vec())),
            positions: state.pos.clone(),
            velocities: state.vel.clone(),
        })
    }
}

/// A number in the shortest decimal form that reads back to the same `f64`: plain notation
/// for moderate magnitudes, scientific otherwise (both are Rust's shortest round-trip output,
/// and both are read by the original `%lf` reader).
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || (1e-5..1e16).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}
