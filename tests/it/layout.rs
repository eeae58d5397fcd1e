//! The layout rules of docs/architecture.md, checked on the source text: `core/` imports nothing
//! from `io/`, `run/`, the CLI or the configuration and touches no file, thread or channel; no
//! import cycle between files nor between folders; no source file over 600 lines; no function
//! outside the tests over 100 lines. Each rule fails with the files and lines that break it.
//! The import rules (what a use is, which cycles count) are `imports`' module doc.

mod imports;

use std::collections::BTreeMap;
use std::path::PathBuf;

const MAX_FILE_LINES: usize = 600;
const MAX_FN_LINES: usize = 100;

/// Every `.rs` file under `src/`, with its module path (`src/io/las/mod.rs` is `io::las`).
pub(crate) fn modules() -> BTreeMap<Vec<String>, PathBuf> {
    let src = crate::common::root().join("src");
    let mut out = BTreeMap::new();
    let mut stack = vec![src.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).expect("src is readable").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            if p.extension().is_none_or(|x| x != "rs") || p.ends_with("main.rs") {
                continue;
            }
            let rel = p.strip_prefix(&src).expect("under src");
            let mut segs: Vec<String> = rel
                .iter()
                .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
                .collect();
            if matches!(segs.last().map(String::as_str), Some("mod" | "lib")) {
                segs.pop();
            }
            out.insert(segs, p);
        }
    }
    out
}

/// The text with comments, string and char literals blanked out (braces and paths inside them
/// do not count), line structure kept.
fn code_only(text: &str) -> String {
    let b: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == '/' && b.get(i + 1) == Some(&'/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
            continue;
        }
        if c == '"' {
            out.push('"');
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    i += 1;
                }
                if b.get(i) == Some(&'\n') {
                    out.push('\n');
                }
                i += 1;
            }
            out.push('"');
            i += 1;
            continue;
        }
        // A char literal ('{', '\n'), not a lifetime ('a).
        if c == '\'' && (b.get(i + 2) == Some(&'\'') || b.get(i + 1) == Some(&'\\')) {
            let end = (i + 1..b.len()).find(|&j| b[j] == '\'' && b[j - 1] != '\\');
            i = end.map_or(b.len(), |e| e + 1);
            out.push_str("' '");
            continue;
        }
        out.push(c);
        i += 1;
    }
    out
}

/// Whether a file holds only unit tests (`tests.rs`, `*_tests.rs`, declared under
/// `#[cfg(test)]` by its parent).
fn is_test_file(path: &std::path::Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n == "tests.rs" || n.ends_with("_tests.rs"))
}

/// The code with its `#[cfg(test)]` items blanked out (lines kept).
fn without_tests(code: &str) -> String {
    let lines: Vec<&str> = code.lines().collect();
    let tests = test_regions(&lines);
    lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            if tests.iter().any(|&(a, b)| i >= a && i <= b) {
                ""
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Line ranges of `#[cfg(test)]` items (test modules and test-only functions).
fn test_regions(code: &[&str]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (i, l) in code.iter().enumerate() {
        if l.trim() == "#[cfg(test)]" {
            if let Some(end) = block_end(code, i + 1) {
                out.push((i, end));
            }
        }
    }
    out
}

/// The line where the block opened at or after line `from` closes.
fn block_end(code: &[&str], from: usize) -> Option<usize> {
    let mut depth = 0i32;
    let mut opened = false;
    for (j, l) in code.iter().enumerate().skip(from) {
        for c in l.chars() {
            match c {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                ';' if !opened && depth == 0 => return Some(j),
                _ => {}
            }
        }
        if opened && depth == 0 {
            return Some(j);
        }
    }
    None
}

#[test]
fn files_and_functions_stay_small() {
    let mut long = Vec::new();
    for path in modules().values() {
        let text = std::fs::read_to_string(path).expect("readable");
        let n = text.lines().count();
        if n > MAX_FILE_LINES {
            long.push(format!(
                "{}: {n} lines (at most {MAX_FILE_LINES})",
                path.display()
            ));
        }
        if is_test_file(path) {
            continue;
        }
        let code = code_only(&text);
        let lines: Vec<&str> = code.lines().collect();
        let tests = test_regions(&lines);
        for (i, l) in lines.iter().enumerate() {
            let t = l.trim_start();
            let is_fn = [
                "fn ",
                "pub fn ",
                "pub(crate) fn ",
                "pub(super) fn ",
                "const fn ",
                "pub const fn ",
                "unsafe fn ",
                "pub unsafe fn ",
            ]
            .iter()
            .any(|p| t.starts_with(p));
            if !is_fn || tests.iter().any(|&(a, b)| i >= a && i <= b) {
                continue;
            }
            if let Some(end) = block_end(&lines, i) {
                if end - i + 1 > MAX_FN_LINES {
                    long.push(format!(
                        "{}:{}: a function of {} lines (at most {MAX_FN_LINES})",
                        path.display(),
                        i + 1,
                        end - i + 1
                    ));
                }
            }
        }
    }
    assert!(long.is_empty(), "too long:\n{}", long.join("\n"));
}

/// The checker itself finds what it must: braces in strings, a long function (the import rules'
/// own check is in `imports`).
#[test]
fn the_checks_catch_what_they_should() {
    let code = code_only("let s = \"{ // not code\"; // a comment with crate::io\nlet c = '{';\n");
    assert!(!code.contains("crate::io") && !code.contains("not code"));
    assert_eq!(code.matches('{').count(), 0, "{code}");
    let f: Vec<String> = (0..120)
        .map(|i| {
            if i == 0 {
                "fn f() {".into()
            } else if i == 119 {
                "}".into()
            } else {
                "x();".into()
            }
        })
        .collect();
    let lines: Vec<&str> = f.iter().map(String::as_str).collect();
    assert_eq!(block_end(&lines, 0), Some(119));
}
