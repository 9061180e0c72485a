//! The crate's modules depend one way: each may use its own layer and the ones below, never a
//! higher one. Reads every `src/**/*.rs`, takes the `crate::<module>` paths in code (comment
//! lines left out) and checks them against this table:
//!
//! | layer | modules | what they hold |
//! |---|---|---|
//! | 1 | `linalg`, `symmetric`, `exact`, `inertia`, `convergence`, `rotors`, `gravity` | arithmetic, ratios, the convergence criterion, the rotors' momentum, the gravity-gradient torque's |
//! | 2 | `settings`, `invariant`, `status` | the paper's functions and settings, the statuses |
//! | 3 | `identifier`, `refined`, `refined_bias`, `extended`, `tensor`, `output_error` | the per-sample estimators and the fits' shared machinery |
//! | 4 | `ratio_fit`, `tensor_fit` | the end-of-flight fits |
//! | 5 | `free_flight` | the free-flight gate |
//! | 6 | `pipeline` | the sample path that composes them |
//!
//! `lib.rs` (the re-exports) and the test-only `test_motion` are outside the table.
use std::path::{Path, PathBuf};

const LAYERS: [&[&str]; 6] = [
    &[
        "linalg",
        "symmetric",
        "exact",
        "inertia",
        "convergence",
        "rotors",
        "gravity",
    ],
    &["settings", "invariant", "status"],
    &[
        "identifier",
        "refined",
        "refined_bias",
        "extended",
        "tensor",
        "output_error",
    ],
    &["ratio_fit", "tensor_fit"],
    &["free_flight"],
    &["pipeline"],
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

/// Every `.rs` file below `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module a file belongs to: its first path component under `src`.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

/// The modules named by `crate::<module>` paths in the code of `text` (comment lines left
/// out), including grouped ones (`crate::{a, b::c}`).
fn uses(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let code = line.trim_start();
        if code.starts_with("//") {
            continue;
        }
        let code = code.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                for item in group[..end].split(',') {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        out.push(name);
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                out.push(name);
            }
        }
    }
    out
}

/// Upward edges: `(module, its layer, used module, its layer)`.
fn upward(src: &Path) -> Vec<(String, usize, String, usize)> {
    let mut files = Vec::new();
    sources(src, &mut files);
    let mut bad = Vec::new();
    for f in files {
        let m = module_of(src, &f);
        if m == "lib" || m == "test_motion" {
            continue;
        }
        let lm = layer_of(&m).unwrap_or_else(|| panic!("module {m} is in no layer"));
        for u in uses(&std::fs::read_to_string(&f).unwrap()) {
            // Items re-exported at the root (`crate::Foo`) are not modules.
            let Some(lu) = layer_of(&u) else {
                continue;
            };
            if lu > lm {
                bad.push((m.clone(), lm + 1, u, lu + 1));
            }
        }
    }
    bad
}

#[test]
fn no_module_uses_a_higher_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let bad = upward(&src);
    assert!(
        bad.is_empty(),
        "upward uses (module, layer, uses, layer): {bad:?}"
    );
}

#[test]
fn the_parser_finds_plain_grouped_and_inline_paths_and_skips_comments() {
    let text = "use crate::linalg::dot;\nuse crate::{pipeline::Pipeline, status};\n\
                // crate::ratio_fit in a comment\nlet x = crate::tensor_fit::f(); // crate::exact\n";
    assert_eq!(uses(text), ["linalg", "pipeline", "status", "tensor_fit"]);
    // And the check fails on an upward use: a layer-1 module naming the pipeline.
    let dir = std::env::temp_dir().join(format!("layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("linalg.rs"), "use crate::pipeline::Pipeline;\n").unwrap();
    std::fs::write(dir.join("pipeline.rs"), "use crate::linalg::dot;\n").unwrap();
    let bad = upward(&dir);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(bad, [("linalg".into(), 1, "pipeline".into(), 6)]);
}
