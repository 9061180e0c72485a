//! Inertia's layers go one way: every module of `inertia/src` may use the modules of its own
//! layer and of the layers below it, never one above. The layers, bottom to top:
//!
//! | layer | modules | what they hold |
//! |---|---|---|
//! | 1 readers | `readers` (with `gyro_filters`, `units`) | the logs read: the [`Recording`] and the `Source` every reader gives |
//! | 2 recording | `recording`, `source`, `survey`, `select`, `unhold`, `vehicle` | the recording and its statistics (median time step, gyro noise), the free flights found in it, the rotor's telemetry unheld, the vehicle file's rotors |
//! | 3 product | `identify` (with `identify/`), `calibrate`, `pool`, `export` | the tensor identified, the rotor calibrated, logs pooled, the report exported |
//! | 4 analyses | `close_loop`, `plots` | what is made of the product: close-the-loop's analysis, the drawings |
//! | 5 CLI | the binary: `main.rs` and its modules `replay`, `telemetry` | the commands |
//!
//! Layer 4 sits above the product path so that `identify`, `calibrate`, `pool` and `export`
//! never import `close_loop` (nor `plots`). The binary reaches `close_loop` through its root
//! API only (never `close_loop::<submodule>`).
//!
//! A module's uses are the `crate::<module>` paths in its code (comments left out), `use`
//! lines and paths in expressions alike, grouped ones (`crate::{a, b}`) included; a root
//! re-export (`crate::read`) counts as the module it comes from (`lib.rs`'s `pub use`), and a
//! top-level `super::<module>` as that module. The binary's files use the library as
//! `inertia::<module>`. A module missing from [`LAYERS`] fails the test: a new module gets
//! its layer here.
//!
//! [`Recording`]: inertia::Recording

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// Every top-level module of the library and of the binary, with its layer.
const LAYERS: &[(&str, u32)] = &[
    ("readers", 1),
    ("recording", 2),
    ("source", 2),
    ("grid", 2),
    ("survey", 2),
    ("select", 2),
    ("unhold", 2),
    ("vehicle", 2),
    ("identify", 3),
    ("calibrate", 3),
    ("pool", 3),
    ("export", 3),
    ("close_loop", 4),
    ("plots", 4),
    ("main", 5),
    ("replay", 5),
    ("telemetry", 5),
];

/// The binary's files (the rest of `src` is the library).
const BINARY: &[&str] = &["main", "replay", "telemetry"];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The top-level module a file belongs to: `readers/csv.rs` and `readers/mod.rs` to
/// `readers`, `identify.rs` to `identify`.
fn module_of(rel: &Path) -> String {
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_str()
        .unwrap();
    first.strip_suffix(".rs").unwrap_or(first).to_string()
}

/// The code of a file without its comments (line, doc and block comments) and with its
/// string and character literals emptied (so that neither a `//` in a string nor a
/// `crate::` in one is taken for code).
fn code(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let ident = |ch: char| ch.is_alphanumeric() || ch == '_';
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        let at = |k: usize| c.get(i + k).copied().unwrap_or('\0');
        let (c0, c1, c2) = (at(0), at(1), at(2));
        if c0 == '/' && c1 == '/' {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if c0 == '/' && c1 == '*' {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if c0 == 'r' && (c1 == '"' || c1 == '#') && !(i > 0 && ident(c[i - 1])) {
            // A raw string: r"..." or r#"..."#.
            let hashes = c[i + 1..].iter().take_while(|&&h| h == '#').count();
            if c.get(i + 1 + hashes) != Some(&'"') {
                out.push('r');
                i += 1;
                continue;
            }
            let close: String = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let body: String = c[i + 2 + hashes..].iter().collect();
            let len = body
                .find(&close)
                .map_or(body.len(), |e| body[..e].chars().count());
            i += 2 + hashes + len + 1 + hashes;
            out.push_str("\"\"");
        } else if c0 == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if c0 == '\'' && c1 == '\\' {
            // An escaped character literal ('\n', '\'', '\u{..}').
            i += 2;
            while i < c.len() && c[i] != '\'' {
                i += 1;
            }
            i += 1;
            out.push_str("' '");
        } else if c0 == '\'' && c2 == '\'' {
            i += 3;
            out.push_str("' '");
        } else {
            out.push(c0);
            i += 1;
        }
    }
    out
}

fn ident_at(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The first segments of the paths after `prefix` (`crate::`, `inertia::`, ...): `a` for
/// `prefix a::b`, `a` and `b` for `prefix {a::x, b}`.
fn heads(code: &str, prefix: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (at, _) in code.match_indices(prefix) {
        // `prefix` must start a path, not end one (`my_crate::` for `crate::`).
        let before = code[..at].chars().next_back();
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_') {
            continue;
        }
        let rest = code[at + prefix.len()..].trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            // Split the group's top-level items by commas.
            let (mut depth, mut item_start) = (0usize, 0usize);
            for (j, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        push_item(&group[item_start..j], &mut out);
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        push_item(&group[item_start..j], &mut out);
                        item_start = j + 1;
                    }
                    _ => {}
                }
            }
        } else {
            push_item(rest, &mut out);
        }
    }
    out
}

fn push_item(item: &str, out: &mut Vec<String>) {
    let head = ident_at(item.trim_start());
    if !head.is_empty() && head != "self" {
        out.push(head.to_string());
    }
}

/// `lib.rs`'s root re-exports: item name -> the module it comes from.
fn root_reexports(lib: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    for line in code(lib).split(';') {
        let Some(rest) = line.trim().strip_prefix("pub use ") else {
            continue;
        };
        let module = ident_at(rest).to_string();
        for name in heads(rest, &format!("{module}::")) {
            map.insert(name, module.clone());
        }
    }
    map
}

/// Module -> the modules it uses, each with the files (and the path) that use it.
type Uses = BTreeMap<String, BTreeMap<String, BTreeSet<String>>>;

/// Every use of one top-level module by another, as [`Uses`]; also the binary's paths into
/// `close_loop` (file, the item named right after `close_loop::`).
fn uses_in(src: &Path) -> (Uses, Vec<(String, String)>) {
    let layer: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let lib = fs::read_to_string(src.join("lib.rs")).unwrap();
    let reexports = root_reexports(&lib);
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let (mut uses, mut into_close_loop) = (Uses::new(), Vec::new());
    for path in files {
        let rel = path.strip_prefix(src).unwrap().to_path_buf();
        let module = module_of(&rel);
        if module == "lib" {
            continue;
        }
        let text = code(&fs::read_to_string(&path).unwrap());
        let binary = BINARY.contains(&module.as_str());
        let mut found = Vec::new();
        // The library as the library sees it, or as the binary does.
        let (lib_prefix, own) = if binary {
            ("inertia::", "crate::")
        } else {
            ("crate::", "")
        };
        for head in heads(&text, lib_prefix) {
            let to = reexports.get(&head).cloned().unwrap_or(head);
            found.push(to);
        }
        if binary {
            // The binary's own modules (`crate::replay`) are its layer.
            for head in heads(&text, own) {
                if layer.contains_key(head.as_str()) {
                    found.push(head);
                }
            }
        }
        for prefix in ["super::", "super::super::"] {
            for head in heads(&text, prefix) {
                if head != module && layer.contains_key(head.as_str()) {
                    found.push(head);
                }
            }
        }
        if binary {
            // `inertia::close_loop::x`, or `close_loop::x` after `use inertia::close_loop`.
            for item in heads(&text, "close_loop::") {
                into_close_loop.push((rel.display().to_string(), item));
            }
        }
        for to in found {
            if to == module {
                continue;
            }
            uses.entry(module.clone())
                .or_default()
                .entry(to)
                .or_default()
                .insert(rel.display().to_string());
        }
    }
    (uses, into_close_loop)
}

/// The uses that break the layers: of a module missing from [`LAYERS`], or of a higher layer.
fn upward(uses: &Uses) -> Vec<String> {
    let layer: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let mut bad = Vec::new();
    for (from, tos) in uses {
        for (to, files) in tos {
            let files: Vec<&str> = files.iter().map(String::as_str).collect();
            match (layer.get(from.as_str()), layer.get(to.as_str())) {
                (Some(lf), Some(lt)) if lt > lf => bad.push(format!(
                    "{from} (layer {lf}) uses {to} (layer {lt}) in {}",
                    files.join(", ")
                )),
                (Some(_), Some(_)) => {}
                _ => bad.push(format!(
                    "{from} uses {to} ({}): give every module its layer in LAYERS",
                    files.join(", ")
                )),
            }
        }
    }
    bad
}

fn table(uses: &Uses) -> String {
    uses.iter()
        .map(|(from, tos)| {
            let tos: Vec<&str> = tos.keys().map(String::as_str).collect();
            format!("  {from} -> {}\n", tos.join(", "))
        })
        .collect()
}

#[test]
fn no_module_uses_a_higher_layer() {
    let src = src();
    let (uses, _) = uses_in(&src);
    // Every file is some layer's: a new top-level module must be placed in LAYERS.
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let layer: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    for f in &files {
        let m = module_of(f.strip_prefix(&src).unwrap());
        assert!(
            m == "lib" || layer.contains_key(m.as_str()),
            "{}: module {m} has no layer in LAYERS",
            f.display()
        );
    }
    let bad = upward(&uses);
    assert!(
        bad.is_empty(),
        "uses against the layers:\n  {}\nall uses:\n{}",
        bad.join("\n  "),
        table(&uses)
    );
    // The check sees the uses that are there (a parser that found nothing would pass).
    assert!(uses["identify"].contains_key("recording"));
    assert!(uses["recording"].contains_key("readers"));
    assert!(uses["main"].contains_key("close_loop"));
}

#[test]
fn the_product_path_never_imports_close_loop() {
    let (uses, _) = uses_in(&src());
    for product in ["identify", "calibrate", "pool", "export"] {
        let tos = uses
            .get(product)
            .map(|t| t.keys().cloned().collect::<Vec<_>>());
        assert!(
            !tos.iter()
                .flatten()
                .any(|t| t == "close_loop" || t == "plots"),
            "{product} uses {tos:?}"
        );
    }
}

#[test]
fn the_binary_uses_close_loop_through_its_root_api() {
    let src = src();
    let (_, into) = uses_in(&src);
    let root = code(&fs::read_to_string(src.join("close_loop/mod.rs")).unwrap());
    let submodules: BTreeSet<String> = heads(&root, "pub mod ").into_iter().collect();
    assert!(submodules.contains("analysis"), "{submodules:?}");
    let deep: Vec<String> = into
        .iter()
        .filter(|(_, item)| submodules.contains(item))
        .map(|(file, item)| format!("{file}: close_loop::{item}"))
        .collect();
    assert!(
        !into.is_empty() && deep.is_empty(),
        "the binary reaches into close_loop's submodules:\n  {}",
        deep.join("\n  ")
    );
}

#[test]
fn the_parser_finds_grouped_reexported_and_inline_paths() {
    let text = code(
        "use crate::{a::X, b};\n// crate::commented\n/* crate::blocked */\nlet s = \"// crate::no\"; let q = '\"'; crate::c::f(); my_crate::d;\nlet r = r#\"crate::raw \" \"#; let l: &'static str = \"\"; use crate::read;",
    );
    assert_eq!(heads(&text, "crate::"), ["a", "b", "c", "read"]);
    let map = root_reexports("pub use readers::{read, Format};\npub use recording::Recording;");
    assert_eq!(map["read"], "readers");
    assert_eq!(map["Recording"], "recording");
    // An upward use is reported, a downward one is not.
    let mut uses = Uses::new();
    uses.entry("readers".into())
        .or_default()
        .entry("identify".into())
        .or_default()
        .insert("readers/x.rs".into());
    uses.entry("identify".into())
        .or_default()
        .entry("readers".into())
        .or_default()
        .insert("identify.rs".into());
    assert_eq!(
        upward(&uses),
        ["readers (layer 1) uses identify (layer 3) in readers/x.rs"]
    );
}
