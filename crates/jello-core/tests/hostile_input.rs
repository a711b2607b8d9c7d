//! Hostile input for the world-file reader: every malformed file must give an error that names
//! the source and the line (never a panic, a hang, a huge allocation or a silent default), and
//! the writer must round-trip every double bit for bit.

#[path = "common/alloc_watch.rs"]
mod alloc_watch;

use alloc_watch::{largest_allocation, total_allocation};
use jello_core::{
    Aabb, ForceField, Integrator, ModelBuilder, Plane, ReadOptions, State, Vec3, World, WorldError,
};

// ---------------------------------------------------------------------------------------------
// Helpers.

const NAME: &str = "name.w";

/// Bytes any parse may allocate in all: [`ALLOCATION_PER_BYTE`] per byte of input (the world
/// holds at most 24 bytes per triple of text, some 40 bytes long; measured: under 0.5), plus
/// [`ALLOCATION_SLACK`] for what a header may claim before its numbers are read (the largest
/// field, 30³ triples, and 1024 triples: 0.67 MB) and the error message. A reader that copied
/// the rest of the text per token, or otherwise did work quadratic in its input through the
/// allocator, would allocate far more. (Time is never measured: a hang shows as a test that
/// never ends.)
const ALLOCATION_PER_BYTE: usize = 4;
const ALLOCATION_SLACK: usize = 1 << 20;

fn parse(bytes: &[u8]) -> Result<World, WorldError> {
    parse_with(bytes, ReadOptions::default())
}

fn parse_with(bytes: &[u8], options: ReadOptions) -> Result<World, WorldError> {
    let (r, total) = total_allocation(|| World::parse(bytes, NAME, options));
    assert!(
        total <= ALLOCATION_PER_BYTE * bytes.len() + ALLOCATION_SLACK,
        "parsing {} bytes allocated {total} bytes",
        bytes.len()
    );
    r
}

/// Asserts `r` is an error naming the source and a line ≥ 1; returns it.
fn expect_err(r: Result<World, WorldError>, what: &str) -> WorldError {
    let e = match r {
        Ok(_) => panic!("{what}: parsed, expected an error"),
        Err(e) => e,
    };
    let shown = e.to_string();
    assert_eq!(e.source_name, NAME, "{what}: {shown}");
    assert!(e.line >= 1, "{what}: no line number in {shown:?}");
    let prefix = format!("{NAME}:{}: ", e.line);
    assert!(
        shown.starts_with(&prefix),
        "{what}: {shown:?} does not start with {prefix:?}"
    );
    assert!(!e.message.is_empty(), "{what}: empty message");
    e
}

/// Asserts `r` is an error at exactly `line` whose message contains every one of `needles`.
fn expect_err_at(r: Result<World, WorldError>, line: usize, needles: &[&str], what: &str) {
    let e = expect_err(r, what);
    assert_eq!(e.line, line, "{what}: wrong line in {e}");
    for n in needles {
        assert!(e.message.contains(n), "{what}: {e} does not mention {n:?}");
    }
}

/// The reference world: the default model with an inclined plane and a small force field, at
/// rest. Its text has a fixed layout (see [`Layout`]).
fn base_world() -> World {
    let plane = Plane::facing([0.0, 0.0, 1.0, 1.0], Vec3::new(0.5, 0.5, 0.5)).unwrap();
    let field = ForceField::from_fn(2, Aabb::classic(), |p| p * 0.5).unwrap();
    let model = ModelBuilder::new()
        .plane(Some(plane))
        .field(Some(field))
        .build()
        .unwrap();
    World::from_simulation(&model, &State::at_rest(&model)).unwrap()
}

/// The world the brief describes: default model plus a 30³ force field, at rest.
fn big_world() -> World {
    let field = ForceField::from_fn(30, Aabb::classic(), |p| p).unwrap();
    let model = ModelBuilder::new().field(Some(field)).build().unwrap();
    World::from_simulation(&model, &State::at_rest(&model)).unwrap()
}

/// Lines of [`base_world`]'s text (1-based).
mod line {
    pub const INTEGRATOR: usize = 1;
    pub const DT_N: usize = 2;
    pub const SPRINGS: usize = 3;
    pub const MASS: usize = 4;
    pub const PLANE_PRESENT: usize = 5;
    pub const PLANE: usize = 6;
    pub const RES: usize = 7;
    pub const FIELD: usize = 8; // 8 triples: lines 8..=15
    pub const POSITIONS: usize = 16; // 512 triples: lines 16..=527
    pub const VELOCITIES: usize = 528; // 512 triples: lines 528..=1039
    pub const LAST: usize = 1039;
}

/// [`base_world`]'s text with token `col` (1-based) of line `line` replaced by `new`.
fn with_token(line: usize, col: usize, new: &str) -> String {
    let text = base_world().to_text();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    assert_eq!(lines.len(), line::LAST, "layout of the base world changed");
    let mut tokens: Vec<&str> = lines[line - 1].split_whitespace().collect();
    tokens[col - 1] = new;
    lines[line - 1] = tokens.join(" ");
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// [`base_world`]'s text with line `line` replaced by `new` (which may hold several lines).
fn with_line(line: usize, new: &str) -> String {
    let text = base_world().to_text();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = new;
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// A fixed-seed 64-bit LCG (Knuth's MMIX constants); the high bits are the output.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }
    fn byte(&mut self) -> u8 {
        (self.next() >> 56) as u8
    }
    fn below(&mut self, n: u64) -> u64 {
        (self.next() >> 33) % n
    }
}

fn assert_bits_eq(a: &World, b: &World) {
    let bits = |v: f64| v.to_bits();
    let vbits = |v: &Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    assert_eq!(a.integrator, b.integrator);
    assert_eq!(a.steps_per_frame, b.steps_per_frame);
    for (name, x, y) in [
        ("dt", a.dt, b.dt),
        ("kElastic", a.k_elastic, b.k_elastic),
        ("dElastic", a.d_elastic, b.d_elastic),
        ("kCollision", a.k_collision, b.k_collision),
        ("dCollision", a.d_collision, b.d_collision),
        ("mass", a.mass, b.mass),
    ] {
        assert_eq!(bits(x), bits(y), "{name}: {x:e} vs {y:e}");
    }
    match (a.plane, b.plane) {
        (None, None) => {}
        (Some(p), Some(q)) => assert_eq!(p.map(bits), q.map(bits), "plane {p:?} vs {q:?}"),
        (p, q) => panic!("plane {p:?} vs {q:?}"),
    }
    match (&a.field, &b.field) {
        (None, None) => {}
        (Some((r, f)), Some((s, g))) => {
            assert_eq!(r, s);
            assert_eq!(f.len(), g.len());
            for (n, (x, y)) in f.iter().zip(g).enumerate() {
                assert_eq!(vbits(x), vbits(y), "field node {n}: {x:?} vs {y:?}");
            }
        }
        (p, q) => panic!("field present {} vs {}", p.is_some(), q.is_some()),
    }
    for (what, xs, ys) in [
        ("position", &a.positions, &b.positions),
        ("velocity", &a.velocities, &b.velocities),
    ] {
        assert_eq!(xs.len(), ys.len());
        for (n, (x, y)) in xs.iter().zip(ys).enumerate() {
            assert_eq!(vbits(x), vbits(y), "{what} {n}: {x:?} vs {y:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The reference worlds themselves are valid.

#[test]
fn base_worlds_parse_and_match_their_layout() {
    let w = base_world();
    let text = w.to_text();
    assert_eq!(text.lines().count(), line::LAST);
    assert_eq!(parse(text.as_bytes()).unwrap(), w);
    assert_eq!(text.lines().nth(line::RES - 1), Some("2"));
    assert_eq!(text.lines().nth(line::PLANE_PRESENT - 1), Some("1"));
    let big = big_world();
    assert_eq!(parse(big.to_text().as_bytes()).unwrap(), big);
}

// ---------------------------------------------------------------------------------------------
// Empty, blank and truncated files.

#[test]
fn empty_file_is_an_error_naming_the_source() {
    let e = parse(b"").unwrap_err();
    assert_eq!(e.source_name, NAME);
    let shown = e.to_string();
    assert!(shown.starts_with(NAME), "{shown}");
    assert!(shown.contains("empty"), "{shown}");
    assert_eq!(e.line, 1, "{shown}");
    assert!(shown.starts_with(&format!("{NAME}:1: ")), "{shown}");
}

#[test]
fn whitespace_only_is_an_error_at_the_last_line() {
    expect_err_at(
        parse(b"   \n\t\n  \r\n \x0b\x0c "),
        4,
        &["integrator", "ends"],
        "whitespace",
    );
    expect_err_at(parse(b" "), 1, &["integrator"], "one space");
    expect_err_at(parse(b"\n"), 2, &["integrator"], "one newline");
}

#[test]
fn header_only_files_say_what_is_missing() {
    expect_err_at(parse(b"RK4"), 1, &["time step"], "integrator only");
    expect_err_at(parse(b"RK4\n0.0005"), 2, &["steps per frame"], "no n");
    expect_err_at(parse(b"RK4\n0.0005 1\n"), 3, &["kElastic"], "no springs");
}

fn check_truncations(w: &World, stride: usize) -> (usize, usize) {
    let text = w.to_text();
    let bytes = text.as_bytes();
    // Where the last token starts: a cut after that point may leave a complete world.
    let last_token_start = text.trim_end().rfind(char::is_whitespace).unwrap() + 1;
    let (mut errors, mut oks) = (0, 0);
    let cuts = (0..bytes.len()).step_by(stride).chain([
        1,
        bytes.len() / 2,
        last_token_start - 1,
        last_token_start,
        bytes.len() - 2,
        bytes.len() - 1,
    ]);
    for cut in cuts {
        let part = &bytes[..cut];
        let what = format!("cut at byte {cut} of {}", bytes.len());
        match parse(part) {
            Ok(got) => {
                assert!(
                    cut > last_token_start,
                    "{what}: parsed although the text is incomplete"
                );
                assert_eq!(got.positions, w.positions, "{what}");
                oks += 1;
            }
            Err(e) if cut == 0 => assert_eq!(e.source_name, NAME),
            Err(e) => {
                let e = expect_err(Err(e), &what);
                // The error is on the last line of what is left (or just after it).
                let lines = part.iter().filter(|&&b| b == b'\n').count() + 1;
                assert!(
                    e.line <= lines,
                    "{what}: error at line {} of {lines}: {e}",
                    e.line
                );
                errors += 1;
            }
        }
    }
    (errors, oks)
}

#[test]
fn truncated_files_are_errors() {
    let (errors, oks) = check_truncations(&big_world(), 997);
    assert!(errors > 1000, "only {errors} truncations tried");
    assert!(
        oks >= 1,
        "cutting the final newline should leave a valid world"
    );
}

#[test]
fn truncated_small_world_at_every_line_start_is_an_error() {
    let w = base_world();
    let text = w.to_text();
    let mut starts: Vec<usize> = text.match_indices('\n').map(|(i, _)| i + 1).collect();
    starts.pop(); // the end of the file
    for (n, &cut) in starts.iter().enumerate() {
        // Cut after line n + 1: the next token would be on line n + 2.
        expect_err_at(
            parse(&text.as_bytes()[..cut]),
            n + 2,
            &["ends here"],
            &format!("cut after line {}", n + 1),
        );
    }
    let (errors, _) = check_truncations(&w, 7);
    assert!(errors > 3000);
}

#[test]
fn a_cut_inside_the_last_number_reads_a_different_but_valid_world() {
    let mut w = base_world();
    w.velocities[511] = Vec3::new(0.0, 0.0, 0.123456789);
    let text = w.to_text();
    let cut = text.len() - 5; // "0.123456789\n" cut to "0.12345"
    let got = parse(&text.as_bytes()[..cut]).unwrap();
    assert_eq!(got.velocities[511].z, 0.12345);
}

// ---------------------------------------------------------------------------------------------
// Non-finite and out-of-range numbers.

const NON_FINITE: &[&str] = &[
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "-Infinity",
    "1e400",
    "-1e400",
    "1e99999999999",
];

#[test]
fn non_finite_numbers_are_errors_in_every_field() {
    let places: &[(&str, usize, usize)] = &[
        ("dt", line::DT_N, 1),
        ("kElastic", line::SPRINGS, 1),
        ("dElastic", line::SPRINGS, 2),
        ("kCollision", line::SPRINGS, 3),
        ("dCollision", line::SPRINGS, 4),
        ("mass", line::MASS, 1),
        ("plane a", line::PLANE, 1),
        ("plane d", line::PLANE, 4),
        ("first force x", line::FIELD, 1),
        ("last force z", line::FIELD + 7, 3),
        ("first position x", line::POSITIONS, 1),
        ("a position y", line::POSITIONS + 100, 2),
        ("last position z", line::VELOCITIES - 1, 3),
        ("first velocity x", line::VELOCITIES, 1),
        ("last velocity z", line::LAST, 3),
    ];
    for &(field, l, col) in places {
        for bad in NON_FINITE {
            expect_err_at(
                parse(with_token(l, col, bad).as_bytes()),
                l,
                &[],
                &format!("{field} = {bad}"),
            );
        }
    }
}

#[test]
fn non_finite_error_says_the_number_is_not_finite() {
    let e = expect_err(
        parse(with_token(line::MASS, 1, "1e400").as_bytes()),
        "mass 1e400",
    );
    assert!(e.message.contains("finite"), "{e}");
    assert!(e.message.contains("1e400"), "{e}");
}

#[test]
fn negative_or_zero_parameters_are_errors() {
    let cases: &[(&str, usize, usize, &str)] = &[
        ("dt", line::DT_N, 1, "-0.0005"),
        ("dt", line::DT_N, 1, "0"),
        ("dt", line::DT_N, 1, "-0"),
        ("kElastic", line::SPRINGS, 1, "-200"),
        ("kElastic", line::SPRINGS, 1, "0"),
        ("dElastic", line::SPRINGS, 2, "-0.25"),
        ("dElastic", line::SPRINGS, 2, "-1"),
        ("kCollision", line::SPRINGS, 3, "-400"),
        ("dCollision", line::SPRINGS, 4, "-0.25"),
        ("mass", line::MASS, 1, "-0.001953125"),
        ("mass", line::MASS, 1, "0"),
    ];
    for &(field, l, col, bad) in cases {
        expect_err_at(
            parse(with_token(l, col, bad).as_bytes()),
            l,
            &[],
            &format!("{field} = {bad}"),
        );
    }
    // Zero damping is allowed.
    let w = parse(with_token(line::SPRINGS, 2, "0").as_bytes()).unwrap();
    assert_eq!(w.d_elastic, 0.0);
    let w = parse(with_token(line::SPRINGS, 4, "0").as_bytes()).unwrap();
    assert_eq!(w.d_collision, 0.0);
}

#[test]
fn steps_per_frame_must_be_a_positive_integer() {
    for bad in [
        "0",
        "1.5",
        "-1",
        "1e3",
        "nan",
        "x",
        "4294967296",
        "99999999999999999999",
    ] {
        expect_err_at(
            parse(with_token(line::DT_N, 2, bad).as_bytes()),
            line::DT_N,
            &["steps per frame"],
            &format!("n = {bad}"),
        );
    }
    let w = parse(with_token(line::DT_N, 2, "7").as_bytes()).unwrap();
    assert_eq!(w.steps_per_frame, 7);
}

#[test]
fn inc_plane_present_must_be_0_or_1() {
    for bad in ["2", "-1", "0.5", "1.0", "yes", "99999999999999999999"] {
        expect_err_at(
            parse(with_token(line::PLANE_PRESENT, 1, bad).as_bytes()),
            line::PLANE_PRESENT,
            &["incPlanePresent"],
            &format!("incPlanePresent = {bad}"),
        );
    }
}

#[test]
fn zero_or_unmeasurable_plane_normal_is_an_error() {
    // Zero, or a length that overflows or underflows: the depth would be 0 or NaN everywhere.
    for plane in [
        "0 0 0 1",
        "0 0 0 0",
        "-0 0 -0 3",
        "1e200 0 0 -1e199",
        "1e-200 1e-200 1e-200 0",
        "5e-324 0 0 0",
    ] {
        expect_err_at(
            parse(with_line(line::PLANE, plane).as_bytes()),
            line::PLANE,
            &["normal"],
            &format!("plane {plane}"),
        );
    }
}

#[test]
fn bad_resolutions_are_errors_without_allocating() {
    for bad in [
        "1",
        "31",
        "-5",
        "1000000000",
        "99999999999999999999",
        "-99999999999999999999",
        "2.0",
        "1e9",
    ] {
        let text = with_token(line::RES, 1, bad);
        let (r, largest) = largest_allocation(|| parse(text.as_bytes()));
        let what = format!("res = {bad}");
        expect_err_at(r, line::RES, &["resolution"], &what);
        assert!(
            largest < 1 << 20,
            "{what}: allocated {largest} bytes at once"
        );
    }
}

#[test]
fn res_zero_means_no_field_and_leftover_triples_are_trailing_data() {
    // The 8 field triples are then read as positions, leaving 8 triples (24 numbers) over.
    let e = expect_err(
        parse(with_token(line::RES, 1, "0").as_bytes()),
        "res = 0 with a field",
    );
    assert_eq!(e.line, line::LAST - 7, "{e}");
    assert!(e.message.contains("end of the file"), "{e}");
}

#[test]
fn every_supported_resolution_reads() {
    for res in [2usize, 3, 17, 30] {
        let field = ForceField::from_fn(res, Aabb::classic(), |p| p * -1.5).unwrap();
        let model = ModelBuilder::new().field(Some(field)).build().unwrap();
        let w = World::from_simulation(&model, &State::at_rest(&model)).unwrap();
        let got = parse(w.to_text().as_bytes()).unwrap();
        assert_bits_eq(&got, &w);
        got.to_simulation().unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// Garbage.

#[test]
fn binary_garbage_is_an_error() {
    let mut rng = Lcg(0x5eed_1234_abcd_0001);
    for n in 0..300 {
        let len = 1 + rng.below(4096) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
        expect_err(parse(&bytes), &format!("garbage #{n} ({len} bytes)"));
    }
}

#[test]
fn garbage_after_a_valid_header_is_an_error() {
    let mut rng = Lcg(42);
    let header = b"RK4\n0.0005 1\n200 0.25 400 0.25\n0.001953125\n0\n0\n".to_vec();
    for n in 0..200 {
        let mut bytes = header.clone();
        let len = 1 + rng.below(2048) as usize;
        bytes.extend((0..len).map(|_| rng.byte()));
        let e = expect_err(parse(&bytes), &format!("header + garbage #{n}"));
        assert!(e.line >= 6, "{e}");
    }
}

#[test]
fn non_utf8_and_nul_bytes_are_errors() {
    // Invalid UTF-8 as the integrator, and inside numbers.
    expect_err_at(
        parse(b"\xff\xfe\n0.0005 1\n"),
        1,
        &["integrator"],
        "0xff 0xfe",
    );
    expect_err_at(parse(b"RK\xc3\n"), 1, &["integrator"], "truncated UTF-8");
    let text = base_world().to_text();
    expect_err_at(
        parse(with_token(line::MASS, 1, "0.00\u{e9}5").as_bytes()),
        line::MASS,
        &["mass"],
        "é in mass",
    );
    // Non-UTF-8 byte in a position.
    let mut bytes = text.clone().into_bytes();
    let at = text.match_indices('\n').nth(line::POSITIONS + 9).unwrap().0 + 1;
    bytes.insert(at, 0x80);
    expect_err_at(
        parse(&bytes),
        line::POSITIONS + 11,
        &["position"],
        "0x80 in a position",
    );
    // NUL bytes: at the start, replacing a separator, in the middle of a number, all NUL.
    expect_err_at(parse(b"\0"), 1, &["integrator"], "one NUL");
    expect_err_at(parse(&[0u8; 4096]), 1, &["integrator"], "all NUL");
    let mut bytes = text.clone().into_bytes();
    bytes.insert(0, 0);
    expect_err_at(parse(&bytes), 1, &["integrator"], "leading NUL");
    let mut bytes = text.clone().into_bytes();
    let sep = text.find("0.0005 1").unwrap() + 6;
    bytes[sep] = 0;
    expect_err_at(
        parse(&bytes),
        line::DT_N,
        &["time step"],
        "NUL as a separator",
    );
    let mut bytes = text.clone().into_bytes();
    let mid = text.find("0.001953125").unwrap() + 4;
    bytes[mid] = 0;
    expect_err_at(parse(&bytes), line::MASS, &["mass"], "NUL in the mass");
    let mut bytes = text.into_bytes();
    bytes.push(0);
    expect_err_at(
        parse(&bytes),
        line::LAST + 1,
        &["end of the file"],
        "NUL at the end",
    );
}

#[test]
fn error_shows_long_tokens_shortened_and_escaped() {
    let long = "9".repeat(100_000) + "x";
    let e = expect_err(
        parse(with_token(line::MASS, 1, &long).as_bytes()),
        "long token",
    );
    assert!(
        e.message.len() < 300,
        "message is {} bytes",
        e.message.len()
    );
    let e = expect_err(parse(b"RK4\n\x01\x02\x1b[31m 1\n"), "control bytes");
    assert!(!e.message.contains('\x1b'), "{e:?}");
}

// ---------------------------------------------------------------------------------------------
// Trailing data, integrators, first token.

#[test]
fn trailing_data_after_the_velocities_is_an_error_naming_its_line() {
    let text = base_world().to_text();
    for (extra, line) in [
        ("0\n", line::LAST + 1),
        ("\n\n\nx", line::LAST + 4),
        ("RK4\n", line::LAST + 1),
        ("0 0 0\n", line::LAST + 1),
    ] {
        let bad = format!("{text}{extra}");
        expect_err_at(
            parse(bad.as_bytes()),
            line,
            &["end of the file"],
            &format!("trailing {extra:?}"),
        );
    }
    // Extra tokens on the last line itself.
    let bad = format!("{} 7\n", text.trim_end());
    expect_err_at(
        parse(bad.as_bytes()),
        line::LAST,
        &["\"7\""],
        "4th number on the last line",
    );
    // Trailing whitespace of every kind is fine.
    let ok = format!("{text} \t\r\n\n\x0b\x0c  \n");
    assert_eq!(parse(ok.as_bytes()).unwrap(), base_world());
}

#[test]
fn unknown_integrator_lists_the_known_names() {
    let text = with_line(line::INTEGRATOR, "IPC");
    let e = expect_err(parse(text.as_bytes()), "IPC");
    assert_eq!(e.line, 1);
    for name in ["IPC", "Euler", "RK2", "RK4", "SymplecticEuler"] {
        assert!(e.message.contains(name), "{e} does not list {name}");
    }
    for (choice, expected) in [
        (Integrator::Rk4, Integrator::Rk4),
        (Integrator::Euler, Integrator::Euler),
    ] {
        let w = parse_with(
            text.as_bytes(),
            ReadOptions {
                integrator: Some(choice),
            },
        )
        .unwrap();
        assert_eq!(w.integrator, expected);
        assert_eq!(
            World {
                integrator: Integrator::Rk4,
                ..w
            },
            base_world()
        );
    }
    // The override does not excuse a word that is not a word.
    let e = parse_with(
        with_line(line::INTEGRATOR, "0.5").as_bytes(),
        ReadOptions {
            integrator: Some(Integrator::Rk4),
        },
    );
    expect_err(e, "number as integrator with override");
}

#[test]
fn integrator_names_match_without_regard_to_case() {
    for (word, expected) in [
        ("rk4", Integrator::Rk4),
        ("EULER", Integrator::Euler),
        ("Euler", Integrator::Euler),
        ("midpoint", Integrator::Rk2),
        ("MP", Integrator::Rk2),
        ("rK2", Integrator::Rk2),
    ] {
        let w = parse(with_line(line::INTEGRATOR, word).as_bytes()).unwrap();
        assert_eq!(w.integrator, expected, "{word}");
    }
}

#[test]
fn a_file_whose_first_token_is_a_number_is_an_error() {
    let text = base_world().to_text();
    // The integrator line left out: "0.0005 1" comes first.
    let without = text.split_once('\n').unwrap().1;
    expect_err_at(
        parse(without.as_bytes()),
        1,
        &["integrator"],
        "no integrator line",
    );
    for first in ["1", "0", "-3", "1e5", "nan", "inf", ".5"] {
        expect_err_at(
            parse(with_line(line::INTEGRATOR, first).as_bytes()),
            1,
            &["integrator"],
            &format!("first token {first}"),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Line endings and round trips.

#[test]
fn crlf_world_parses_and_equals_the_lf_one() {
    let w = base_world();
    let lf = w.to_text();
    let crlf = lf.replace('\n', "\r\n");
    assert_ne!(lf, crlf);
    let got = parse(crlf.as_bytes()).unwrap();
    assert_eq!(got, w);
    assert_bits_eq(&got, &parse(lf.as_bytes()).unwrap());
    let big = big_world();
    assert_eq!(
        parse(big.to_text().replace('\n', "\r\n").as_bytes()).unwrap(),
        big
    );
    // Errors in CRLF files report the same lines as in LF files.
    let bad = with_token(line::MASS, 1, "nan").replace('\n', "\r\n");
    expect_err_at(parse(bad.as_bytes()), line::MASS, &[], "CRLF nan mass");
    // A world with no line breaks at all reads the same (line breaks carry no meaning).
    let one_line = lf.replace('\n', " ");
    assert_eq!(parse(one_line.as_bytes()).unwrap(), w);
}

const AWKWARD: &[f64] = &[
    1.0 / 3.0,
    -1.0 / 3.0,
    1e-300,
    5e-324,
    -5e-324,
    -0.0,
    0.0,
    1e300,
    -1e300,
    0.1 + 0.2,
    f64::MAX,
    f64::MIN,
    f64::MIN_POSITIVE,
    f64::from_bits(0x000f_ffff_ffff_ffff), // largest subnormal
    1e-5,
    9.999999999999999e-6,
    1e16,
    9999999999999998.0,
    123456789012345680.0,
    1.0 / 7.0,
    std::f64::consts::PI,
    0.001953125,
    0.001953,
];

#[test]
fn round_trip_is_bit_exact_for_awkward_doubles() {
    let mut w = base_world();
    let positive: Vec<f64> = AWKWARD.iter().copied().filter(|&v| v > 0.0).collect();
    let non_negative: Vec<f64> = AWKWARD.iter().copied().filter(|&v| v >= 0.0).collect();
    for (n, p) in w.positions.iter_mut().enumerate() {
        let a = |k: usize| AWKWARD[(3 * n + k) % AWKWARD.len()];
        *p = Vec3::new(a(0), a(1), a(2));
    }
    for (n, v) in w.velocities.iter_mut().enumerate() {
        let a = |k: usize| AWKWARD[(5 * n + k + 1) % AWKWARD.len()];
        *v = Vec3::new(a(0), a(1), a(2));
    }
    if let Some((_, forces)) = &mut w.field {
        for (n, f) in forces.iter_mut().enumerate() {
            *f = Vec3::new(AWKWARD[n], -AWKWARD[n + 1], AWKWARD[n + 2]);
        }
    }
    w.plane = Some([1.0 / 3.0, -0.0, 5e-324, 0.1 + 0.2]);
    for (i, &dt) in positive.iter().enumerate() {
        w.dt = dt;
        w.mass = positive[(i + 1) % positive.len()];
        w.k_elastic = positive[(i + 2) % positive.len()];
        w.k_collision = positive[(i + 3) % positive.len()];
        w.d_elastic = non_negative[i % non_negative.len()];
        w.d_collision = non_negative[(i + 5) % non_negative.len()];
        let text = w.to_text();
        let got = parse(text.as_bytes()).unwrap();
        assert_bits_eq(&got, &w);
        // And the text is a fixed point.
        assert_eq!(got.to_text(), text);
    }
    // -0.0 keeps its sign.
    let got = parse(w.to_text().as_bytes()).unwrap();
    assert!(got.plane.unwrap()[1].is_sign_negative());
    assert_eq!(got.positions[1].z.to_bits(), (-0.0f64).to_bits());
}

#[test]
fn round_trip_is_bit_exact_for_random_doubles() {
    let mut rng = Lcg(0xdead_beef);
    let mut w = base_world();
    for _ in 0..20 {
        let mut finite = || loop {
            let v = f64::from_bits(rng.next());
            if v.is_finite() {
                return v;
            }
        };
        for p in w.positions.iter_mut().chain(w.velocities.iter_mut()) {
            *p = Vec3::new(finite(), finite(), finite());
        }
        w.dt = finite().abs().max(f64::MIN_POSITIVE);
        w.mass = finite().abs().max(5e-324);
        let got = parse(w.to_text().as_bytes()).unwrap();
        assert_bits_eq(&got, &w);
    }
}

#[test]
fn round_trip_of_a_stepped_simulation_continues_bit_for_bit() {
    let w = base_world();
    let mut a = jello_core::Simulation::from_world(&w).unwrap();
    a.state.vel[0] = Vec3::new(0.3, -0.7, 1.0 / 3.0);
    a.advance(25).unwrap();
    let saved = a.to_world().unwrap();
    let reread = parse(saved.to_text().as_bytes()).unwrap();
    assert_bits_eq(&reread, &saved);
    let mut b = jello_core::Simulation::from_world(&reread).unwrap();
    a.advance(25).unwrap();
    b.advance(25).unwrap();
    for (p, q) in a.state.pos.iter().zip(&b.state.pos) {
        assert_eq!(
            [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()],
            [q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]
        );
    }
}
