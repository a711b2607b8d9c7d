//! Where things are in the text a scene was read from, so that an error found after serde has
//! read the file (a negative density, an unknown integrator, a body that starts inside another)
//! names the line of the key at fault rather than the table's header or no line at all.

use std::collections::HashMap;

use toml::de::{DeTable, DeValue};

/// Lines (from 1) of the keys of a scene's text, by dotted path: `simulation.integrator`,
/// `body.1` (the header of the second `[[body]]`, counted from 0), `body.1.density`,
/// `obstacle.0.radius`, `body.0.cube.size`. Where a scene came from, not part of its value: two
/// scenes with the same content are equal wherever they were read (see [`PartialEq`]).
#[derive(Clone, Debug, Default)]
pub(super) struct SourceLines(HashMap<String, usize>);

impl PartialEq for SourceLines {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl SourceLines {
    /// The lines of every key of `text`, a TOML document serde has already read without error.
    pub(super) fn of(text: &str) -> Self {
        let mut lines = SourceLines::default();
        if let Ok(document) = DeTable::parse(text) {
            let mut index = LineIndex::new(text);
            lines.walk(&mut index, "", document.get_ref());
            for table in ["body", "obstacle"] {
                for n in 0.. {
                    match header_line(text, table, n) {
                        0 => break,
                        line => lines.0.insert(format!("{table}.{n}"), line),
                    };
                }
            }
        }
        lines
    }

    /// Records the line of each key of `table` (under `prefix`) and of the tables within it; an
    /// array is entered only when it holds tables (a saved state's thousands of positions have
    /// no keys).
    fn walk(&mut self, index: &mut LineIndex, prefix: &str, table: &DeTable<'_>) {
        for (key, value) in table {
            let path = format!("{prefix}{}", key.get_ref());
            self.0.insert(path.clone(), index.line(key.span().start));
            match value.get_ref() {
                DeValue::Table(inner) => self.walk(index, &format!("{path}."), inner),
                DeValue::Array(items) => {
                    for (n, item) in items.iter().enumerate() {
                        if let DeValue::Table(inner) = item.get_ref() {
                            self.walk(index, &format!("{path}.{n}."), inner);
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The line of `path` (0 when the file has no such key, as a scene made in memory has
    /// none).
    pub(super) fn line(&self, path: &str) -> usize {
        self.0.get(path).copied().unwrap_or(0)
    }

    /// The line of `key` within the table at `table` when the file gives it there, else the
    /// table's own line.
    pub(super) fn key_or_table(&self, table: &str, key: Option<&str>) -> usize {
        key.map(|k| self.line(&format!("{table}.{k}")))
            .filter(|&l| l > 0)
            .unwrap_or_else(|| self.line(table))
    }
}

/// Byte offsets to lines, for offsets visited mostly in increasing order.
struct LineIndex {
    /// Byte offset of the start of each line.
    starts: Vec<usize>,
}

impl LineIndex {
    fn new(text: &str) -> Self {
        let starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        LineIndex { starts }
    }

    /// The line (from 1) holding byte `offset`.
    fn line(&mut self, offset: usize) -> usize {
        self.starts.partition_point(|&s| s <= offset)
    }
}

/// Line of the header of the `n`-th `[[table]]` (from 0; 0 when not found).
pub(super) fn header_line(text: &str, table: &str, n: usize) -> usize {
    let spaced = format!("[[ {table} ]]");
    let tight = format!("[[{table}]]");
    text.lines()
        .enumerate()
        .filter(|(_, l)| {
            let t = l.trim_start();
            t.starts_with(&tight) || t.starts_with(&spaced)
        })
        .nth(n)
        .map_or(0, |(n, _)| n + 1)
}

/// Where `key` is written as a key (`key =`, or `"key" =`) in `text`: its byte offset, the first
/// such place. For an error serde reports at a whole table (an unknown key), to point at the key.
pub(super) fn find_key(text: &str, key: &str) -> Option<usize> {
    let quoted = format!("\"{key}\"");
    for candidate in [key, quoted.as_str()] {
        let mut from = 0;
        while let Some(found) = text[from..].find(candidate) {
            let start = from + found;
            let end = start + candidate.len();
            let before = text[..start].chars().next_back();
            let starts_key = before.is_none_or(|c| c.is_whitespace() || c == '{' || c == ',');
            let after = text[end..].trim_start_matches([' ', '\t']);
            if starts_key && after.starts_with('=') {
                return Some(start);
            }
            from = end;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_of_tables_and_arrays_of_tables_have_their_lines() {
        let text = "[simulation]\nintegrator = \"RK4\"\n\n[[body]]\nname = \"a\"\n\
                    cube = { points = [2, 2, 2], size = [1.0, 1.0, 1.0] }\n[[body]]\n\
                    density = 5.0\n";
        let lines = SourceLines::of(text);
        assert_eq!(lines.line("simulation.integrator"), 2);
        assert_eq!(lines.line("body.0"), 4);
        assert_eq!(lines.line("body.0.cube.size"), 6);
        assert_eq!(lines.line("body.1"), 7);
        assert_eq!(lines.line("body.1.density"), 8);
        assert_eq!(lines.key_or_table("body.1", Some("mass")), 7);
        assert_eq!(lines.line("body.2"), 0);
    }

    #[test]
    fn a_key_is_found_where_it_is_written_as_a_key_only() {
        let text = "name = \"raduis\"\nx = { raduis = 1 }\n";
        assert_eq!(find_key(text, "raduis"), text.find("raduis ="));
        assert_eq!(find_key("\"raduis\" = 2", "raduis"), Some(0));
        assert_eq!(find_key("radius = 2", "raduis"), None);
    }
}
