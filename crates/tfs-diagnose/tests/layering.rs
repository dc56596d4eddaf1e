//! The crate's modules form layers: scoring primitives at the bottom, orchestration on top, and
//! no import cycle between modules (two modules that import each other cannot be read, tested or
//! moved one at a time).
//!
//! The graph is read from the sources: a module is a file of `src/` (a folder's files belong to
//! the module of the same name), and it depends on every module it names as `crate::module`
//! outside comments — in a path, or in a `use crate::{…}` group. An item the crate root
//! re-exports (`crate::Result`) counts as a dependency on the module that defines it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Module name → the modules it depends on.
type Graph = BTreeMap<String, BTreeSet<String>>;

/// The source without comments: `//` to the end of the line (outside string literals, well
/// enough for this crate's sources, whose strings never hold `//` before a `crate::`).
fn code(source: &str) -> String {
    source
        .lines()
        .map(|line| match line.find("//") {
            Some(k) if !line[..k].contains('"') => &line[..k],
            _ => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The first path segment of every `crate::` path in `code`, groups opened.
fn crate_paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(k) = rest.find("crate::") {
        rest = &rest[k + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            // Top-level items of the group, up to its closing brace.
            let mut depth = 0usize;
            let mut item_start = true;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => item_start = true,
                    c if c.is_whitespace() => {}
                    _ if item_start && depth == 0 => {
                        out.push(ident(&group[i..]).to_string());
                        item_start = false;
                    }
                    _ => {}
                }
            }
        } else {
            out.push(ident(rest).to_string());
        }
    }
    out
}

/// The items the crate root re-exports (`pub use module::{…}`), with their module.
fn root_items(lib: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let lib = code(lib);
    let mut rest = lib.as_str();
    while let Some(k) = rest.find("pub use ") {
        rest = &rest[k + "pub use ".len()..];
        let end = rest.find(';').unwrap_or(rest.len());
        let stmt = &rest[..end];
        let module = ident(stmt).to_string();
        let items = stmt[module.len()..].trim_start_matches("::");
        let items = items.trim_start_matches('{').trim_end_matches('}');
        for item in items.split(',') {
            let name = item.trim().rsplit("::").next().unwrap_or("").trim();
            if !name.is_empty() {
                out.insert(name.to_string(), module.clone());
            }
        }
    }
    out
}

/// The module graph of the crate whose sources are in `src`.
fn graph(src: &Path) -> Graph {
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs");
    let items = root_items(&lib);
    let mut files = Vec::new();
    for entry in std::fs::read_dir(src).expect("src") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            let module = path.file_name().unwrap().to_string_lossy().to_string();
            for sub in std::fs::read_dir(&path).expect("folder") {
                files.push((module.clone(), sub.expect("entry").path()));
            }
        } else if path.extension().is_some_and(|e| e == "rs") {
            let module = path.file_stem().unwrap().to_string_lossy().to_string();
            files.push((module, path));
        }
    }
    let modules: BTreeSet<String> = files.iter().map(|(m, _)| m.clone()).collect();
    let mut g = Graph::new();
    for (module, path) in files {
        let text = std::fs::read_to_string(&path).expect("source");
        let deps = g.entry(module.clone()).or_default();
        for seg in crate_paths(&code(&text)) {
            // A module by its name; a root item by the module that defines it; any other name is
            // the root's own item.
            let target = if modules.contains(&seg) {
                seg
            } else {
                items
                    .get(&seg)
                    .cloned()
                    .unwrap_or_else(|| "lib".to_string())
            };
            if target != module {
                deps.insert(target);
            }
        }
    }
    g
}

/// A cycle of `g` as the path of modules around it, if there is one.
fn cycle(g: &Graph) -> Option<Vec<String>> {
    // Depth-first, with the modules on the current path marked.
    fn visit(
        g: &Graph,
        m: &str,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|p| p == m) {
            let mut c = path[k..].to_vec();
            c.push(m.to_string());
            return Some(c);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for d in g.get(m).into_iter().flatten() {
            if let Some(c) = visit(g, d, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    g.keys()
        .find_map(|m| visit(g, m, &mut Vec::new(), &mut done))
}

#[test]
fn the_modules_of_the_crate_import_each_other_without_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let g = graph(&src);
    if let Some(c) = cycle(&g) {
        panic!(
            "import cycle between modules of tfs-diagnose: {}",
            c.join(" -> ")
        );
    }
    // The graph was read: the scan's orchestration reaches its stages, and the root re-exports
    // resolve to their modules.
    let explain = &g["explain"];
    for stage in ["scan", "judge", "null", "rank", "evidence", "verdict"] {
        assert!(
            explain.contains(stage),
            "explain should use {stage}: {explain:?}"
        );
    }
    assert!(g["effects"].contains("error"), "{:?}", g["effects"]);
}

/// The checker itself finds a cycle through a `use crate::{…}` group and a root re-export, and
/// ignores a comment.
#[test]
fn the_checker_finds_a_cycle_and_ignores_comments() {
    let dir = std::env::temp_dir().join(format!("tfs-layering-{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("b")).unwrap();
    let write = |p: &str, s: &str| std::fs::write(src.join(p), s).unwrap();
    write("lib.rs", "mod a;\nmod b;\nmod c;\npub use c::Thing;\n");
    write("a.rs", "use crate::{b::X, Thing};\n");
    write("b.rs", "pub struct X;\n");
    write(
        "c.rs",
        "// uses crate::a in words only\npub struct Thing;\n",
    );
    assert_eq!(cycle(&graph(&src)), None);
    // A file in the folder of `b` that imports `a`: a -> b -> a.
    write(
        "b/inner.rs",
        "use crate::a::Y; // and crate::c in a comment\n",
    );
    let g = graph(&src);
    assert_eq!(g["a"], ["b", "c"].map(String::from).into());
    assert_eq!(g["b"], ["a"].map(String::from).into());
    let c = cycle(&g).expect("a cycle");
    assert_eq!(c.first(), c.last());
    assert!(
        c.contains(&"a".to_string()) && c.contains(&"b".to_string()),
        "{c:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
