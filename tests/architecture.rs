//! The shape of `src/`, read from its own code (issue 44): every module and
//! what it names of the others — `use` trees and inline paths through
//! `crate::`, `super::` and `self::`, outside comments and inline test
//! modules. A module declaring its children and naming their items is not
//! an edge; a child naming its parent's items is.
//!
//! Checked here: the graph has no circle; the layers point one way (core ←
//! domain ← store ← app ← http ← startup ← cli); no handler module (one
//! whose functions the routers route) names another; no file outside the
//! tests is over 600 lines; every module opens with a `//!` saying what it
//! owns; `docs/developers.md`'s map lists every module there is and none
//! that is not; and every metric the code names is described (Prometheus's
//! `# HELP`, which `promtool check metrics` asks for).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use regex::Regex;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Every module of the crate: its path (`http::ui::viewer`, `` for the
/// root) and its file.
fn modules() -> BTreeMap<String, PathBuf> {
    let src = Path::new(ROOT).join("src");
    let mut found = BTreeMap::new();
    let mut dirs = vec![src.clone()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
                continue;
            }
            // The binary is a crate of its own, over the library's API.
            if path.extension().is_none_or(|e| e != "rs") || path == src.join("main.rs") {
                continue;
            }
            let rel = path.strip_prefix(&src).unwrap().with_extension("");
            let mut parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
                parts.pop();
            }
            // A sibling `tests.rs` is an out-of-line test module.
            if parts.last().is_some_and(|p| p == "tests") {
                continue;
            }
            found.insert(parts.join("::"), path);
        }
    }
    found
}

/// A file's code: without comments, and without an inline test module (a
/// `#[cfg(test)]` at the start of a line, to the end of the file, as this
/// codebase writes them).
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let text = match text.find("\n#[cfg(test)]\nmod tests {") {
        Some(i) => &text[..i],
        None => &text,
    };
    text.lines()
        .map(|l| match l.find("//") {
            // Keep `//` inside string literals (URLs) roughly: only a
            // comment when the line's code before it has balanced quotes.
            Some(i) if l[..i].matches('"').count() % 2 == 0 => &l[..i],
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths a `use` tree names, written out (`a::{b, c::{d}}` →
/// `a::b`, `a::c::d`).
fn expand(tree: &str) -> Vec<String> {
    let renamed = Regex::new(r"\s+as\s+[A-Za-z_][A-Za-z0-9_]*").unwrap();
    let tree: String = renamed
        .replace_all(tree, "")
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    fn walk(prefix: &str, tree: &str, out: &mut Vec<String>) {
        match tree.find('{') {
            None => out.push(format!("{prefix}{tree}")),
            Some(open) => {
                let head = &tree[..open];
                let inner = &tree[open + 1..tree.len() - 1];
                let mut depth = 0;
                let mut start = 0;
                let mut parts = Vec::new();
                for (i, c) in inner.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => depth -= 1,
                        ',' if depth == 0 => {
                            parts.push(&inner[start..i]);
                            start = i + 1;
                        }
                        _ => {}
                    }
                }
                parts.push(&inner[start..]);
                for p in parts.into_iter().filter(|p| !p.is_empty()) {
                    walk(&format!("{prefix}{head}"), p, out);
                }
            }
        }
    }
    let mut out = Vec::new();
    walk("", &tree, &mut out);
    out
}

/// The module `path` (from module `from`, whose file is a directory's
/// `mod.rs` when `dir`) names, if it names one of `known`: the longest
/// prefix that is a module.
fn resolve(from: &str, path: &str, known: &BTreeMap<String, PathBuf>) -> Option<String> {
    let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let mut base: Vec<&str> = if from.is_empty() {
        Vec::new()
    } else {
        from.split("::").collect()
    };
    match segs.first().copied() {
        Some("crate") => {
            base.clear();
            segs.remove(0);
        }
        Some("self") => {
            segs.remove(0);
        }
        Some("super") => {
            while segs.first() == Some(&"super") {
                base.pop();
                segs.remove(0);
            }
        }
        _ => return None,
    }
    let full: Vec<&str> = base.into_iter().chain(segs).collect();
    (1..=full.len())
        .rev()
        .map(|n| full[..n].join("::"))
        .find(|m| known.contains_key(m))
}

/// Module → the modules it names (its own children excluded).
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let known = modules();
    let uses = Regex::new(r"(?s)\buse\s+((?:crate|super|self)::[^;]*);").unwrap();
    let inline = Regex::new(r"\b(?:crate|super|self)(?:::[A-Za-z_][A-Za-z0-9_]*)+").unwrap();
    let mut edges = BTreeMap::new();
    for (m, path) in &known {
        let code = code(path);
        let mut named = BTreeSet::new();
        let mut paths: Vec<String> = uses
            .captures_iter(&code)
            .flat_map(|c| expand(&c[1]))
            .collect();
        paths.extend(inline.find_iter(&code).map(|p| p.as_str().to_owned()));
        for p in paths {
            if let Some(t) = resolve(m, &p, &known)
                && t != *m
                && !(m.is_empty() || t.starts_with(&format!("{m}::")))
            {
                named.insert(t);
            }
        }
        edges.insert(m.clone(), named);
    }
    edges
}

/// The circles of `g`: its strongly connected components of more than one
/// module (Tarjan).
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Walk<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(w: &mut Walk<'a>, v: &'a str) {
        let n = w.index.len();
        w.index.insert(v, n);
        w.low.insert(v, n);
        w.stack.push(v);
        w.on.insert(v);
        for t in &w.g[v] {
            let t = t.as_str();
            if !w.index.contains_key(t) {
                visit(w, t);
                let l = w.low[v].min(w.low[t]);
                w.low.insert(v, l);
            } else if w.on.contains(t) {
                let l = w.low[v].min(w.index[t]);
                w.low.insert(v, l);
            }
        }
        if w.low[v] == w.index[v] {
            let mut scc = Vec::new();
            while let Some(t) = w.stack.pop() {
                w.on.remove(t);
                scc.push(t.to_owned());
                if t == v {
                    break;
                }
            }
            if scc.len() > 1 {
                scc.sort();
                w.found.push(scc);
            }
        }
    }
    let mut w = Walk {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in g.keys() {
        if !w.index.contains_key(v.as_str()) {
            visit(&mut w, v);
        }
    }
    w.found
}

#[test]
fn the_import_graph_has_no_circle() {
    let g = graph();
    // The reader sees what it reads: the graph is not empty, and the edges
    // it must find are found.
    assert!(
        g["http::calibrations"].contains("app::submit"),
        "{:?}",
        g["http::calibrations"]
    );
    assert!(g["app::submit"].contains("store"), "{:?}", g["app::submit"]);
    let found = circles(&g);
    assert!(found.is_empty(), "import circles in src/: {found:#?}");
}

#[test]
fn a_circle_is_found_when_there_is_one() {
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec!["a"]),
    ]
    .into_iter()
    .map(|(m, ts)| (m.to_owned(), ts.into_iter().map(str::to_owned).collect()))
    .collect();
    assert_eq!(circles(&g), vec![vec!["a", "b", "c"]]);
    assert_eq!(
        expand("super::{a, b::{c, d as e}, f}"),
        ["super::a", "super::b::c", "super::b::d", "super::f"]
    );
}

/// The layer a module belongs to, bottom first.
fn layer(m: &str) -> usize {
    let top = m.split("::").next().unwrap_or_default();
    match top {
        "domain" => 0,
        "store" => 1,
        "app" => 2,
        "telemetry" => 2,
        "http" => 3,
        "startup" => 4,
        "cli" | "client" | "main" => 5,
        _ => 6,
    }
}

#[test]
fn the_layers_point_one_way() {
    let g = graph();
    let mut up = Vec::new();
    for (m, ts) in &g {
        for t in ts {
            if layer(t) > layer(m) {
                up.push(format!("{m} → {t}"));
            }
        }
    }
    assert!(up.is_empty(), "names of a higher layer: {up:#?}");
}

/// The modules whose functions the routers route.
fn handlers() -> BTreeSet<String> {
    let routed = Regex::new(
        r"(?:routes!\(|get\(|post\(|put\(|delete\(|\.post\(|\.put\()\s*([a-z_]+)::[a-z_]+",
    )
    .unwrap();
    let mut found = BTreeSet::new();
    for (file, prefix) in [
        ("src/http/mod.rs", "http"),
        ("src/http/ui/mod.rs", "http::ui"),
    ] {
        let text = std::fs::read_to_string(Path::new(ROOT).join(file)).unwrap();
        for c in routed.captures_iter(&text) {
            found.insert(format!("{prefix}::{}", &c[1]));
        }
    }
    found
}

#[test]
fn no_handler_names_another() {
    let hs = handlers();
    for h in [
        "http::calibrations",
        "http::reviews",
        "http::triads",
        "http::ui::calibration",
    ] {
        assert!(hs.contains(h), "{h} is routed: {hs:?}");
    }
    let g = graph();
    let mut found = Vec::new();
    for h in &hs {
        for t in g.get(h).into_iter().flatten() {
            if hs.contains(t) {
                found.push(format!("{h} → {t}"));
            }
        }
    }
    assert!(found.is_empty(), "handlers naming handlers: {found:#?}");
}

/// Lines a person reads at one sitting, at most.
const MAX_LINES: usize = 600;

#[test]
fn no_file_is_too_long_to_read() {
    let long: Vec<String> = modules()
        .values()
        .filter_map(|p| {
            let n = std::fs::read_to_string(p).unwrap().lines().count();
            (n > MAX_LINES).then(|| format!("{} ({n} lines)", p.display()))
        })
        .collect();
    assert!(long.is_empty(), "files over {MAX_LINES} lines: {long:#?}");
}

#[test]
fn every_module_says_what_it_owns() {
    let silent: Vec<String> = modules()
        .values()
        .filter(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            !text.trim_start().starts_with("//!")
        })
        .map(|p| p.display().to_string())
        .collect();
    assert!(
        silent.is_empty(),
        "modules without a `//!` doc: {silent:#?}"
    );
}

#[test]
fn the_map_lists_every_module() {
    let map = std::fs::read_to_string(Path::new(ROOT).join("docs/developers.md")).unwrap();
    let start = map
        .find("<!-- module map -->")
        .expect("docs/developers.md has a module map");
    let end = map.find("<!-- end of module map -->").unwrap();
    let listed: BTreeSet<String> = Regex::new(r"`((?:[a-z_0-9]+::)*[a-z_0-9]+)`")
        .unwrap()
        .captures_iter(&map[start..end])
        .map(|c| c[1].to_owned())
        .collect();
    let there: BTreeSet<String> = modules().into_keys().filter(|m| !m.is_empty()).collect();
    let missing: Vec<_> = there.difference(&listed).collect();
    let gone: Vec<_> = listed.difference(&there).collect();
    assert!(
        missing.is_empty(),
        "modules the map does not list: {missing:?}"
    );
    assert!(
        gone.is_empty(),
        "the map lists modules there are not: {gone:?}"
    );
}

/// The metrics the code records, by the names written in its `counter!`,
/// `gauge!` and `histogram!` calls, and those `describe_*!` describes.
fn metrics() -> (BTreeSet<String>, BTreeSet<String>) {
    let named = Regex::new(r#"(?:^|[^a-z_])(?:counter|gauge|histogram)!\(\s*"([a-z_]+)""#).unwrap();
    let described = Regex::new(r#"describe_(?:counter|gauge|histogram)!\(\s*"([a-z_]+)""#).unwrap();
    let (mut used, mut told) = (BTreeSet::new(), BTreeSet::new());
    for path in modules().values() {
        let code = code(path);
        used.extend(named.captures_iter(&code).map(|c| c[1].to_owned()));
        told.extend(described.captures_iter(&code).map(|c| c[1].to_owned()));
    }
    (used, told)
}

#[test]
fn every_metric_is_described() {
    let (used, told) = metrics();
    assert!(used.len() >= 15, "the metrics' calls are found: {used:?}");
    let silent: Vec<&String> = used.difference(&told).collect();
    assert!(
        silent.is_empty(),
        "metrics without a description: {silent:?}"
    );
}
