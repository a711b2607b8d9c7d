//! The core's folders stay layered (docs/architecture.md): each module uses only the modules
//! before it in [`LAYERS`]: the model depends on nothing above it, contact and forces read the
//! model, the integrators call forces and contact, the file formats build models. Every
//! `crate::` path in the sources (comments and unit tests left out) is checked.

use std::fs;
use std::path::{Path, PathBuf};

/// The crate's top-level modules, from the bottom up.
const LAYERS: [&str; 12] = [
    "vec3",
    "compute",
    "model",
    "state",
    "contact",
    "forces",
    "diagnostics",
    "integrate",
    "formats",
    "surface",
    "benchmark",
    "simulation",
];

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).expect("the source folder") {
        let path = entry.expect("a folder entry").path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a source file without its comments and its unit-test modules (a test may build
/// a model from anywhere).
fn code(text: &str) -> String {
    let lines: Vec<&str> = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect();
    let mut kept = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let test_module = lines[i].trim_start().starts_with("#[cfg(")
            && lines[i].contains("test")
            && lines
                .get(i + 1)
                .is_some_and(|l| l.trim_start().starts_with("mod ") && l.contains('{'));
        if !test_module {
            kept.push(lines[i]);
            i += 1;
            continue;
        }
        // Skip to the line that closes the module's brace.
        let mut depth = 0i32;
        i += 1;
        while i < lines.len() {
            depth += braces(lines[i]);
            i += 1;
            if depth <= 0 {
                break;
            }
        }
    }
    kept.join("\n")
}

/// Opening minus closing braces on a line, outside string and character literals.
fn braces(line: &str) -> i32 {
    let (mut depth, mut in_string, mut chars) = (0, false, line.chars().peekable());
    while let Some(c) = chars.next() {
        match c {
            '\\' if in_string => {
                chars.next();
            }
            '"' => in_string = !in_string,
            '\'' if !in_string => {
                // A character literal such as '{' (a lifetime has no closing quote nearby).
                let literal: String = chars.clone().take(3).collect();
                if literal.chars().nth(1) == Some('\'') {
                    chars.nth(1);
                }
            }
            '{' if !in_string => depth += 1,
            '}' if !in_string => depth -= 1,
            _ => {}
        }
    }
    depth
}

/// The top-level modules named by the `crate::` paths of `code`, with a grouped import
/// (`use crate::{a, b::c}`) counted for each of its names.
fn modules_used(code: &str) -> Vec<String> {
    let mut used = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        let after = &rest[i + "crate::".len()..];
        if let Some(group) = after.strip_prefix('{') {
            let close = group.find('}').unwrap_or(group.len());
            // Names at the group's top level: the first segment of each entry.
            let mut depth = 0;
            let mut entry = String::new();
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        used.push(first_segment(&entry));
                        entry.clear();
                        continue;
                    }
                    _ => {}
                }
                entry.push(c);
            }
            used.push(first_segment(&entry));
            rest = &group[close.min(group.len())..];
        } else {
            used.push(first_segment(after));
            rest = after;
        }
    }
    used.retain(|m| !m.is_empty());
    used
}

fn first_segment(path: &str) -> String {
    path.trim_start()
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

#[test]
fn each_module_uses_only_the_modules_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    let layer = |name: &str| LAYERS.iter().position(|&l| l == name);
    let mut wrong = Vec::new();
    let mut checked = 0;
    for file in &files {
        let rel = file.strip_prefix(&src).expect("under src");
        let top = rel
            .components()
            .next()
            .and_then(|c| c.as_os_str().to_str())
            .expect("a file name")
            .trim_end_matches(".rs");
        let name = rel.file_name().and_then(|n| n.to_str()).expect("a name");
        if top == "lib" || name == "tests.rs" || name == "test_models.rs" {
            continue;
        }
        let own = layer(top).unwrap_or_else(|| {
            panic!(
                "{}: a module missing from LAYERS: place it there",
                rel.display()
            )
        });
        let text = fs::read_to_string(file).expect("a readable source");
        for used in modules_used(&code(&text)) {
            checked += 1;
            // A name the crate root re-exports would hide which module it comes from.
            let Some(theirs) = layer(&used) else {
                wrong.push(format!(
                    "{} uses crate::{used}: name its own module instead",
                    rel.display()
                ));
                continue;
            };
            if theirs > own {
                wrong.push(format!(
                    "{} ({top}) uses crate::{used}, which is above it",
                    rel.display()
                ));
            }
        }
    }
    assert!(
        checked > 200,
        "only {checked} paths found: is the parser broken?"
    );
    assert!(
        wrong.is_empty(),
        "imports against the layers:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn grouped_and_plain_paths_are_both_read() {
    let text = "use crate::{model::Model, forces::{a, b}};\nlet x = crate::integrate::step;";
    assert_eq!(modules_used(text), ["model", "forces", "integrate"]);
    assert_eq!(code("x // crate::formats\ny"), "x \ny");
    let with_tests = "a\n#[cfg(test)]\nmod tests {\n    fn f() { let c = '{'; }\n}\nb";
    assert_eq!(code(with_tests), "a\nb");
}
