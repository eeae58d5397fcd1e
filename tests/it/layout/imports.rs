//! The import rules of docs/architecture.md, checked on the source text (see `layout`).
//!
//! Uses: file A uses file B when A's shipped code (tests left out) names an item of B, by a path
//! after `crate::`, `super::`, `self::` or a child module's name; a path through a `pub use`
//! leads to the file that defines the item. Declaring a child (`mod x;`) and re-exporting
//! (`pub use x::Y;`) are no uses, unless the file also names `Y` elsewhere.
//!
//! Files: the uses have no cycle, except one that stays inside a folder and passes through the
//! folder's `mod.rs`, the module's hub (its children use the items it declares, and it may
//! use them: `estimate/mod.rs` builds the estimators of `estimate/jet.rs`, which uses its
//! `Curvature`). A cycle that leaves the folder counts, however it closes: `jet.rs` using
//! `surface.rs`, which uses `principal_from_tangent` of `estimate/mod.rs`, which uses
//! `jet.rs`. So does any cycle that no hub closes (siblings using each other).
//!
//! Folders: in every folder, the entries (its files but `mod.rs`, and its subfolders, each
//! standing for everything under it) have no cycle, where entry A uses entry B when a file in
//! or under A uses a file in or under B. Of `io/`: `las/` uses `crs.rs` when any file under
//! `las/` uses `crs.rs`, and `crs.rs`, `las/` and `source/` may not go round.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use super::{code_only, is_test_file, modules, without_tests};

fn ident_at(b: &[char], mut i: usize) -> (String, usize) {
    let start = i;
    while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
        i += 1;
    }
    (b[start..i].iter().collect(), i)
}

/// The paths named from `at` on (after `crate::` or `super::`): `a::b::c`, or every member of
/// a `{...}` group, each as segments.
fn paths_from(b: &[char], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let mut segs = prefix;
    loop {
        if b.get(i) == Some(&'{') {
            i += 1;
            loop {
                while i < b.len() && (b[i].is_whitespace() || b[i] == ',') {
                    i += 1;
                }
                if i >= b.len() || b[i] == '}' {
                    return;
                }
                let before = i;
                paths_from(b, i, segs.clone(), out);
                // Skip this member (to the next comma or the group's end, nested groups whole).
                let mut depth = 0;
                while i < b.len() {
                    match b[i] {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => break,
                        _ => {}
                    }
                    i += 1;
                }
                if i == before {
                    return;
                }
            }
        }
        let (id, j) = ident_at(b, i);
        if id.is_empty() {
            out.push(segs);
            return;
        }
        segs.push(id);
        i = j;
        if b.get(i) == Some(&':') && b.get(i + 1) == Some(&':') {
            i += 2;
        } else {
            out.push(segs);
            return;
        }
    }
}

/// A module path from the crate root (`["io", "las"]` is `src/io/las/mod.rs`).
type Module = Vec<String>;

/// For each source file, the files whose items it names, each with the line of the first use.
type Graph = BTreeMap<Module, BTreeMap<Module, usize>>;

/// A path a file names: its segments from the crate root, the line it starts on, and the name
/// a `pub use` of it re-exports (None outside a `pub use`).
struct Named {
    path: Module,
    line: usize,
    reexported: Option<String>,
}

/// The paths `code` (the text of `module`'s file) names: after `crate::`, `super::`, `self::`
/// or the name of one of its child modules (`children`), each member of a `{...}` group apart.
fn named_paths(module: &[String], code: &str, children: &BTreeSet<String>) -> Vec<Named> {
    let b: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let mut line = 1;
    for i in 0..b.len() {
        if b[i] == '\n' {
            line += 1;
        }
        let boundary =
            i == 0 || !(b[i - 1].is_alphanumeric() || b[i - 1] == '_' || b[i - 1] == ':');
        if !boundary {
            continue;
        }
        let at = |s: &str, j: usize| b[j..].iter().take(s.len()).copied().eq(s.chars());
        let (base, from) = if at("crate::", i) {
            (Vec::new(), i + 7)
        } else if at("super::", i) {
            // The parent of the module this file is (a mod.rs file is its folder's module).
            let mut base = module[..module.len().saturating_sub(1)].to_vec();
            let mut j = i + 7;
            while at("super::", j) {
                base.pop();
                j += 7;
            }
            (base, j)
        } else if at("self::", i) {
            (module.to_vec(), i + 6)
        } else {
            let (id, j) = ident_at(&b, i);
            if !(children.contains(&id) && at("::", j)) {
                continue;
            }
            (module.to_vec(), i)
        };
        let mut paths = Vec::new();
        paths_from(&b, from, base, &mut paths);
        // The statement this path starts: a `pub use` (`pub(crate) use`) re-exports it.
        let start = b[..i]
            .iter()
            .rposition(|&c| matches!(c, ';' | '{' | '}'))
            .map_or(0, |s| s + 1);
        let head: String = b[start..i].iter().collect();
        let words: Vec<&str> = head.split_whitespace().collect();
        let reexport = words.len() >= 2
            && words[words.len() - 1] == "use"
            && words[words.len() - 2].starts_with("pub");
        for mut path in paths {
            if path.last().is_some_and(|s| s == "self") {
                path.pop();
            }
            let reexported = reexport.then(|| path.last().cloned().unwrap_or_default());
            out.push(Named {
                path,
                line,
                reexported,
            });
        }
    }
    out
}

/// The file that defines what `path` names: the deepest module with a file, or, when that
/// module re-exports the next segment (`reexports`), the file of what it re-exports.
fn resolve(
    path: &[String],
    all: &BTreeMap<Module, PathBuf>,
    reexports: &BTreeMap<Module, BTreeMap<String, Module>>,
    depth: usize,
) -> Option<Module> {
    let m = (0..=path.len())
        .rev()
        .map(|n| path[..n].to_vec())
        .find(|m| all.contains_key(m))?;
    let via = path.get(m.len()).and_then(|n| reexports.get(&m)?.get(n));
    if let Some(target) = via.filter(|_| depth < 8) {
        let mut p = target.clone();
        p.extend_from_slice(&path[m.len() + 1..]);
        if let Some(t) = resolve(&p, all, reexports, depth + 1) {
            return Some(t);
        }
    }
    Some(m)
}

/// The direct children of `module` that have a file.
fn children_of(module: &[String], all: &BTreeMap<Module, PathBuf>) -> BTreeSet<String> {
    all.keys()
        .filter(|k| k.len() == module.len() + 1 && k.starts_with(module))
        .map(|k| k[module.len()].clone())
        .collect()
}

/// The file graph of `all`, whose shipped code (tests blanked) is `code`. A path through a
/// `pub use` leads to the file defining the item; the `pub use` line itself is no use unless
/// the file names the item elsewhere (re-exporting is not using).
fn graph(all: &BTreeMap<Module, PathBuf>, code: &BTreeMap<Module, String>) -> Graph {
    let mut named = BTreeMap::new();
    let mut reexports: BTreeMap<Module, BTreeMap<String, Module>> = BTreeMap::new();
    for (m, text) in code {
        let paths = named_paths(m, text, &children_of(m, all));
        for p in &paths {
            if let Some(name) = &p.reexported {
                reexports
                    .entry(m.clone())
                    .or_default()
                    .insert(name.clone(), p.path.clone());
            }
        }
        named.insert(m.clone(), paths);
    }
    let mut g = Graph::new();
    for (m, paths) in named {
        // The file's code without its `pub use` statements: where a re-exported name is used.
        let rest = strip_pub_uses(&code[&m]);
        let used = |name: &str| {
            rest.match_indices(name).any(|(i, _)| {
                let word = |c: char| c.is_alphanumeric() || c == '_';
                !rest[..i].ends_with(word) && !rest[i + name.len()..].starts_with(word)
            })
        };
        let out = g.entry(m.clone()).or_default();
        for p in paths {
            if p.reexported.as_deref().is_some_and(|n| !used(n)) {
                continue;
            }
            if let Some(t) = resolve(&p.path, all, &reexports, 0).filter(|t| *t != m) {
                out.entry(t).or_insert(p.line);
            }
        }
    }
    g
}

/// `code` with every `pub use ...;` statement blanked.
fn strip_pub_uses(code: &str) -> String {
    let mut out = code.to_string();
    for pat in ["pub use ", "pub(crate) use ", "pub(super) use "] {
        while let Some(i) = out.find(pat) {
            let end = out[i..].find(';').map_or(out.len(), |e| i + e + 1);
            out.replace_range(i..end, &" ".repeat(end - i));
        }
    }
    out
}

/// Whether `m` is a hub: a folder's `mod.rs` (or `lib.rs`), with modules under it.
fn is_hub(m: &[String], g: &Graph) -> bool {
    g.keys().any(|k| k.len() > m.len() && k.starts_with(m))
}

/// A cycle of `g` that breaks the file rule (see the module doc), as the files in order (the
/// first again at the end). First any cycle without a hub's use of its own folder; then, hub
/// by hub, a shortest closed walk through the hub that leaves its folder (found breadth-first
/// over (file, left the folder yet) pairs, without the hubs of the folders around it).
fn file_cycle(g: &Graph) -> Option<Vec<Module>> {
    let down = |a: &Module, b: &Module| b.len() > a.len() && b.starts_with(a);
    let plain: Graph = g
        .iter()
        .map(|(a, out)| {
            let kept = out.iter().filter(|(b, _)| !down(a, b));
            (a.clone(), kept.map(|(b, l)| (b.clone(), *l)).collect())
        })
        .collect();
    if let Some(c) = any_cycle(&plain) {
        return Some(c);
    }
    for hub in g.keys().filter(|m| is_hub(m, g)) {
        let around = |m: &Module| m.len() < hub.len() && hub.starts_with(m) && is_hub(m, g);
        let mut prev: BTreeMap<(Module, bool), (Module, bool)> = BTreeMap::new();
        let mut queue = std::collections::VecDeque::from([(hub.clone(), false)]);
        while let Some((v, left)) = queue.pop_front() {
            for w in g[&v].keys().filter(|w| !around(w)) {
                let next = (w.clone(), left || !w.starts_with(hub));
                if prev.contains_key(&next) || next == (hub.clone(), false) {
                    continue;
                }
                prev.insert(next.clone(), (v.clone(), left));
                if next == (hub.clone(), true) {
                    let mut walk = vec![hub.clone()];
                    let mut at = next;
                    while at != (hub.clone(), false) {
                        at = prev[&at].clone();
                        walk.push(at.0.clone());
                    }
                    walk.reverse();
                    return Some(walk);
                }
                queue.push_back(next);
            }
        }
    }
    None
}

/// Some cycle of `g` (depth first), as nodes with the first again at the end.
fn any_cycle<K: Ord + Clone, V>(g: &BTreeMap<K, BTreeMap<K, V>>) -> Option<Vec<K>> {
    fn visit<K: Ord + Clone, V>(
        m: &K,
        g: &BTreeMap<K, BTreeMap<K, V>>,
        state: &mut BTreeMap<K, bool>,
        stack: &mut Vec<K>,
    ) -> Option<Vec<K>> {
        match state.get(m) {
            Some(true) => return None,
            Some(false) => {
                let at = stack.iter().position(|s| s == m).unwrap_or(0);
                let mut cycle = stack[at..].to_vec();
                cycle.push(m.clone());
                return Some(cycle);
            }
            None => {}
        }
        state.insert(m.clone(), false);
        stack.push(m.clone());
        for n in g.get(m).into_iter().flat_map(|o| o.keys()) {
            if let Some(c) = visit(n, g, state, stack) {
                return Some(c);
            }
        }
        stack.pop();
        state.insert(m.clone(), true);
        None
    }
    let mut state = BTreeMap::new();
    g.keys()
        .find_map(|m| visit(m, g, &mut state, &mut Vec::new()))
}

/// A cycle that breaks the folder rule (see the module doc): the folder whose entries form it,
/// and the entries in order (the first again at the end).
fn folder_cycle(g: &Graph) -> Option<(Module, Vec<Module>)> {
    for folder in g.keys().filter(|m| is_hub(m, g)) {
        let entry = |m: &Module| {
            (m.len() > folder.len() && m.starts_with(folder)).then(|| m[..=folder.len()].to_vec())
        };
        let mut entries: BTreeMap<Module, BTreeMap<Module, ()>> = BTreeMap::new();
        for (a, out) in g {
            let Some(ea) = entry(a) else { continue };
            let targets = entries.entry(ea.clone()).or_default();
            for eb in out.keys().filter_map(entry).filter(|eb| *eb != ea) {
                targets.insert(eb, ());
            }
        }
        if let Some(c) = any_cycle(&entries) {
            return Some((folder.clone(), c));
        }
    }
    None
}

/// The file of `m`, from the crate's root (`src/io/las/mod.rs`).
fn show(all: &BTreeMap<Module, PathBuf>, m: &Module) -> String {
    let p = all.get(m).cloned().unwrap_or_default();
    let root = crate::common::root();
    p.strip_prefix(&root).unwrap_or(&p).display().to_string()
}

/// A use in `g` from a file in (or under) `a` to one in (or under) `b`: `file:line -> file`.
fn witness(g: &Graph, all: &BTreeMap<Module, PathBuf>, a: &Module, b: &Module) -> String {
    g.iter()
        .filter(|(f, _)| f.starts_with(a))
        .flat_map(|(f, out)| out.iter().map(move |(t, l)| (f, t, l)))
        .find(|(_, t, _)| t.starts_with(b))
        .map_or(String::from("?"), |(f, t, l)| {
            format!("{}:{l} -> {}", show(all, f), show(all, t))
        })
}

/// The graph of the shipped code under `src/`, with the files.
fn source_graph() -> (BTreeMap<Module, PathBuf>, Graph, BTreeMap<Module, String>) {
    let all = modules();
    let code: BTreeMap<Module, String> = all
        .iter()
        .map(|(m, path)| {
            let text = std::fs::read_to_string(path).expect("readable");
            // Test modules may use the test kit and anything else: only shipped code counts.
            let code = if is_test_file(path) {
                String::new()
            } else {
                without_tests(&code_only(&text))
            };
            (m.clone(), code)
        })
        .collect();
    let g = graph(&all, &code);
    (all, g, code)
}

#[test]
fn core_is_pure() {
    let (all, g, code) = source_graph();
    assert!(all.len() > 40, "found only {} source files", all.len());
    let mut impure = Vec::new();
    for (m, out) in g
        .iter()
        .filter(|(m, _)| m.first().is_some_and(|s| s == "core"))
    {
        for (r, line) in out {
            if r.first().is_none_or(|s| s != "core") {
                let path = all[m].display();
                impure.push(format!("{path}:{line} uses crate::{}", r.join("::")));
            }
        }
        for (n, line) in code[m].lines().enumerate() {
            for banned in [
                "std::fs",
                "std::thread",
                "crossbeam",
                "std::sync::mpsc",
                "std::net",
                "File::",
            ] {
                if line.contains(banned) {
                    impure.push(format!("{}:{}: {banned}", all[m].display(), n + 1));
                }
            }
        }
    }
    assert!(
        impure.is_empty(),
        "core/ must be pure:\n{}",
        impure.join("\n")
    );
}

#[test]
fn no_import_cycle_between_files() {
    let (all, g, _) = source_graph();
    if let Some(c) = file_cycle(&g) {
        let steps: Vec<String> = c
            .windows(2)
            .map(|w| {
                format!(
                    "{}:{} -> {}",
                    show(&all, &w[0]),
                    g[&w[0]][&w[1]],
                    show(&all, &w[1])
                )
            })
            .collect();
        panic!("import cycle between files:\n  {}", steps.join("\n  "));
    }
}

#[test]
fn no_import_cycle_between_folders() {
    let (all, g, _) = source_graph();
    if let Some((folder, c)) = folder_cycle(&g) {
        let names: Vec<String> = c.iter().map(|e| e.join("::")).collect();
        let steps: Vec<String> = c
            .windows(2)
            .map(|w| witness(&g, &all, &w[0], &w[1]))
            .collect();
        panic!(
            "import cycle between the entries of crate::{}: {}\n  {}",
            folder.join("::"),
            names.join(" -> "),
            steps.join("\n  ")
        );
    }
}

/// The checker itself finds what it must: paths, uses, both kinds of cycle, and not a module's
/// hub using its children.
#[test]
fn the_import_checks_catch_what_they_should() {
    let m = |s: &str| -> Module {
        s.split("::")
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect()
    };
    let build = |files: &[(&str, &str)]| {
        let all: BTreeMap<Module, PathBuf> = files
            .iter()
            .map(|(n, _)| (m(n), PathBuf::from(n)))
            .collect();
        let code = files.iter().map(|(n, c)| (m(n), c.to_string())).collect();
        graph(&all, &code)
    };
    // crate::io -> io; super::Other -> core (the parent); super::a is itself: left out. A
    // `pub use` of a child is no use; a path through it leads to the child.
    let g = build(&[
        ("", ""),
        (
            "core",
            "pub mod a;\npub mod b;\npub use b::Thing;\npub struct Other;",
        ),
        (
            "core::a",
            "use crate::io::{x, y};\nuse super::{a::Mine, Other};",
        ),
        ("core::b", ""),
        ("core::c", "use crate::core::Thing;"),
        ("io", ""),
    ]);
    assert_eq!(
        g[&m("core::a")].keys().collect::<Vec<_>>(),
        [&m("core"), &m("io")]
    );
    assert!(g[&m("core")].is_empty());
    assert_eq!(g[&m("core::c")].keys().collect::<Vec<_>>(), [&m("core::b")]);
    // A hub and its children using each other is no cycle; through a file outside the folder
    // (jet -> surface -> estimate/mod.rs -> jet) it is.
    let estimate = (
        "core::estimate",
        "pub mod jet;\npub struct Curvature;\nfn build() { jet::Jet; }",
    );
    let jet = (
        "core::estimate::jet",
        "use super::Curvature;\nfn f() { crate::core::surface::g(); }",
    );
    let lower = ("core::surface", "use crate::core::geometry::P;");
    let cyclic = ("core::surface", "use crate::core::estimate::Curvature;");
    let tree = [
        ("", ""),
        ("core", ""),
        ("core::geometry", ""),
        estimate,
        jet,
    ];
    let ok = build(&[&tree[..], &[lower]].concat());
    assert_eq!(file_cycle(&ok), None);
    assert_eq!(folder_cycle(&ok), None);
    let bad = build(&[&tree[..], &[cyclic]].concat());
    let names = |c: Vec<Module>| c.iter().map(|x| x.join("::")).collect::<Vec<_>>();
    assert_eq!(
        file_cycle(&bad).map(names),
        Some(vec![
            "core::estimate".to_string(),
            "core::estimate::jet".into(),
            "core::surface".into(),
            "core::estimate".into(),
        ])
    );
    // Folders: no file cycle (convert -> source/mod.rs -> extra_bytes), but las/ and source/
    // use each other.
    let g = build(&[
        ("", ""),
        ("io", ""),
        ("io::las", ""),
        ("io::las::extra_bytes", ""),
        ("io::las::convert", "use crate::io::source::Property;"),
        ("io::source", "use crate::io::las::extra_bytes::ScalarType;"),
    ]);
    assert_eq!(file_cycle(&g), None);
    let (folder, c) = folder_cycle(&g).expect("a folder cycle");
    assert_eq!((folder, names(c).len()), (m("io"), 3));
}
