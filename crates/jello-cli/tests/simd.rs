//! `JELLO_SIMD` from the command line: each tier this CPU runs saves the same bytes, `jello bench`
//! reports the tier it ran, and a tier that cannot run is a usage error before anything runs.

use std::path::PathBuf;
use std::process::{Command, Output};

use jello_core::compute::simd::Tier;

fn jello(simd: Option<&str>, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_jello"));
    cmd.args(args).env_remove("JELLO_SIMD");
    if let Some(value) = simd {
        cmd.env("JELLO_SIMD", value);
    }
    cmd.output().expect("cannot start jello")
}

fn examples() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

#[test]
fn every_tier_saves_the_same_bytes() {
    let dir = std::env::temp_dir().join(format!("jello-simd-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let world = examples().join("rotate.w");
    let mut saved: Vec<(Tier, Vec<u8>)> = Vec::new();
    for tier in Tier::ALL.into_iter().filter(|t| t.is_supported()) {
        let out = dir.join(format!("{}.w", tier.name()));
        let run = jello(
            Some(tier.name()),
            &[
                "run",
                world.to_str().unwrap(),
                "--steps",
                "400",
                "-q",
                "--save",
                out.to_str().unwrap(),
            ],
        );
        assert!(run.status.success(), "{tier}: {run:?}");
        saved.push((tier, std::fs::read(&out).unwrap()));
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let (first, reference) = &saved[0];
    for (tier, bytes) in &saved[1..] {
        assert!(
            bytes == reference,
            "the {first} and {tier} tiers saved different states"
        );
    }
}

#[test]
fn bench_reports_the_tier_it_ran() {
    for tier in Tier::ALL.into_iter().filter(|t| t.is_supported()) {
        let run = jello(
            Some(tier.name()),
            &["bench", "--size", "4", "--seconds", "0.05", "--json"],
        );
        assert!(run.status.success(), "{run:?}");
        let json = String::from_utf8(run.stdout).unwrap();
        assert!(
            json.contains(&format!("\"simd\": \"{}\"", tier.describe())),
            "{json}"
        );
    }
    // Unset: the best tier.
    let run = jello(None, &["bench", "--size", "4", "--seconds", "0.05"]);
    let text = String::from_utf8(run.stdout).unwrap();
    assert!(text.contains(Tier::best().describe()), "{text}");
}

#[test]
fn a_tier_that_cannot_run_is_a_usage_error() {
    let mut bad = vec!["sse7".to_string()];
    bad.extend(
        Tier::ALL
            .into_iter()
            .filter(|t| !t.is_supported())
            .map(|t| t.name().to_string()),
    );
    for value in bad {
        let run = jello(Some(&value), &["info", "nonexistent.w"]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{value}: {stderr}");
        assert!(
            stderr.contains("JELLO_SIMD") && stderr.contains(&value),
            "{stderr}"
        );
    }
}
