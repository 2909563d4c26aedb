//! `--set key=value` overrides, made in the scene's text in place, and where each line of the
//! overridden text came from, so that errors are still located in the file.

use super::line_col;

/// Where the lines of a scene text with `--set` overrides came from: the overrides are made in
/// place ([`apply_override`]), so every line of the file is kept verbatim except those holding
/// an overridden value, and inserted keys add lines. `lines[k]` is the file's line (1-based)
/// that line `k + 1` of the text is, or `None` for a line an override wrote.
#[derive(Clone, Debug)]
pub(super) struct Origin {
    overrides: Vec<String>,
    lines: Vec<Option<usize>>,
}

/// Where an offset of a scene's text is, for error messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Place {
    /// 1-based line and column in the file.
    At(usize, usize),
    /// On a line written by an override (the `--set` argument, or all of them when the line
    /// cannot be told apart).
    Override(String),
}

impl Origin {
    /// Aligns the lines of `text` (the file with the overrides made in place) with those of
    /// `file`: equal lines in order are the file's (a longest common subsequence, or a greedy
    /// match for very long texts), the rest the overrides'.
    pub(super) fn new(file: &str, text: &str, overrides: &[String]) -> Origin {
        let a: Vec<&str> = text.lines().collect();
        let b: Vec<&str> = file.lines().collect();
        let mut lines = vec![None; a.len()];
        if a.len().saturating_mul(b.len()) <= 4_000_000 {
            // lcs[i][j]: the longest common subsequence of a[i..] and b[j..].
            let w = b.len() + 1;
            let mut lcs = vec![0u32; (a.len() + 1) * w];
            for i in (0..a.len()).rev() {
                for j in (0..b.len()).rev() {
                    lcs[i * w + j] = if a[i] == b[j] {
                        lcs[(i + 1) * w + j + 1] + 1
                    } else {
                        lcs[(i + 1) * w + j].max(lcs[i * w + j + 1])
                    };
                }
            }
            let (mut i, mut j) = (0, 0);
            while i < a.len() && j < b.len() {
                if a[i] == b[j] {
                    lines[i] = Some(j + 1);
                    i += 1;
                    j += 1;
                } else if lcs[(i + 1) * w + j] >= lcs[i * w + j + 1] {
                    i += 1;
                } else {
                    j += 1;
                }
            }
        } else {
            let mut j = 0;
            for (i, line) in a.iter().enumerate() {
                if let Some(k) = b[j..].iter().position(|l| l == line) {
                    j += k;
                    lines[i] = Some(j + 1);
                    j += 1;
                }
            }
        }
        Origin {
            overrides: overrides.to_vec(),
            lines,
        }
    }

    /// Where `offset` of `text` is.
    fn place(&self, text: &str, offset: usize) -> Place {
        let (line, col) = line_col(text, offset);
        match self.lines.get(line - 1) {
            Some(Some(file_line)) => Place::At(*file_line, col),
            _ => {
                // The override whose key names the line's key (`key = …`), else all of them.
                let line_text = text.lines().nth(line - 1).unwrap_or("");
                let key = line_text
                    .split('=')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .trim_matches(|c| c == '"' || c == '\'' || c == '[' || c == ']');
                let named = self.overrides.iter().rev().find(|o| {
                    let path = o.split('=').next().unwrap_or("");
                    !key.is_empty() && path.trim().split('.').any(|p| p == key)
                });
                Place::Override(named.cloned().unwrap_or_else(|| self.overrides.join(" ")))
            }
        }
    }
}

/// A place in a document being overridden: a key's item, a table of an array of tables, or
/// a value inside an inline table or an array.
enum Cursor<'d> {
    Item(&'d mut toml_edit::Item),
    Table(&'d mut toml_edit::Table),
    Value(&'d mut toml_edit::Value),
}

/// `part` as an index into a list of `n` entries.
fn index(part: &str, n: usize) -> Result<usize, String> {
    let i: usize = part
        .parse()
        .map_err(|_| format!("`{part}` is not an index"))?;
    if i < n {
        Ok(i)
    } else {
        Err(format!("index {i} out of range ({n} entries)"))
    }
}

/// Sets `a.b.0.c = value` in a TOML document (numbers index arrays and arrays of tables;
/// inline tables are entered as tables; missing tables are created) **in place**: the other
/// lines keep their text, and a replaced value its line, so that error locations can be
/// given in the file ([`Origin`]).
pub(super) fn apply_override(
    doc: &mut toml_edit::DocumentMut,
    assignment: &str,
) -> Result<(), String> {
    use toml_edit::{Item, Value};
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE".to_string())?;
    let parsed: toml_edit::DocumentMut = format!("v = {}", value.trim())
        .parse()
        .map_err(|e: toml_edit::TomlError| format!("bad value: {}", one_line(e.message())))?;
    let mut value = parsed
        .get("v")
        .and_then(Item::as_value)
        .cloned()
        .ok_or_else(|| "bad value".to_string())?;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.trim().is_empty()) {
        return Err("empty key".to_string());
    }
    let (last, path) = parts.split_last().ok_or_else(|| "empty key".to_string())?;
    let mut cur = Cursor::Table(doc.as_table_mut());
    for part in path {
        cur = match cur {
            Cursor::Table(t) | Cursor::Item(Item::Table(t)) => {
                Cursor::Item(t.entry(part).or_insert_with(toml_edit::table))
            }
            Cursor::Item(Item::ArrayOfTables(a)) => {
                let i = index(part, a.len())?;
                Cursor::Table(a.get_mut(i).expect("an index in range"))
            }
            Cursor::Item(Item::Value(v)) | Cursor::Value(v) => match v {
                Value::InlineTable(t) => Cursor::Value(
                    t.entry(*part)
                        .or_insert_with(|| Value::InlineTable(Default::default())),
                ),
                Value::Array(a) => {
                    let i = index(part, a.len())?;
                    Cursor::Value(a.get_mut(i).expect("an index in range"))
                }
                _ => return Err(format!("`{part}`: not a table")),
            },
            Cursor::Item(Item::None) => return Err(format!("`{part}`: not a table")),
        };
    }
    // A replaced value keeps the spaces around it.
    let mut replace = |old: &mut Value| {
        *value.decor_mut() = old.decor().clone();
        *old = value.clone();
    };
    match cur {
        Cursor::Table(t) | Cursor::Item(Item::Table(t)) => match t.get_mut(last) {
            Some(Item::Value(old)) => replace(old),
            Some(old) => *old = Item::Value(value),
            None => {
                t.insert(last, Item::Value(value));
            }
        },
        Cursor::Item(Item::Value(v)) | Cursor::Value(v) => match v {
            Value::InlineTable(t) => match t.get_mut(last) {
                Some(old) => replace(old),
                None => {
                    t.insert(*last, value);
                }
            },
            Value::Array(a) => {
                let i = index(last, a.len())?;
                replace(a.get_mut(i).expect("an index in range"));
            }
            _ => return Err(format!("`{last}`: parent is not a table")),
        },
        Cursor::Item(Item::ArrayOfTables(a)) => {
            let i = index(last, a.len())?;
            return Err(format!("`{last}`: entry {i} is a table; set its keys"));
        }
        Cursor::Item(Item::None) => return Err(format!("`{last}`: parent is not a table")),
    }
    Ok(())
}

/// Where byte `offset` of a scene text is: in the file, through `origin` when overrides
/// wrote the text.
pub(super) fn place(text: &str, origin: Option<&Origin>, offset: usize) -> Place {
    match origin {
        Some(origin) => origin.place(text, offset),
        None => {
            let (line, col) = line_col(text, offset);
            Place::At(line, col)
        }
    }
}

/// A parser's message on one line (the TOML parsers' span several).
pub(super) fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}
