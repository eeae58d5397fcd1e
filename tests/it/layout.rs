//! The layout rules of docs/architecture.md, checked on the source text: `core/` imports nothing
//! from `io/`, `run/`, the CLI or the configuration and touches no file, thread or channel; no
//! import cycle between files nor between folders; no source file over 600 lines; no function
//! outside the tests over 100 lines; every citation of docs/algorithms.md names one of its
//! headings. Each rule fails with the files and lines that break it.
//! The import rules (what a use is, which cycles count) are `imports`' module doc.

mod imports;

use std::collections::{BTreeMap, BTreeSet};
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

/// The sections of docs/algorithms.md: `N` for each `## N. Title` heading and `N.M` for each
/// `### N.M Title` heading.
fn algorithm_sections(doc: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in doc.lines() {
        let (level, rest) = if let Some(r) = line.strip_prefix("### ") {
            (3, r)
        } else if let Some(r) = line.strip_prefix("## ") {
            (2, r)
        } else {
            continue;
        };
        let number = rest.split_whitespace().next().unwrap_or("");
        let number = if level == 2 {
            number.strip_suffix('.').unwrap_or("")
        } else {
            number
        };
        let parts: Vec<&str> = number.split('.').collect();
        let numeric = parts
            .iter()
            .all(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()));
        if numeric && parts.len() == level - 1 {
            out.insert(number.to_string());
        }
    }
    out
}

/// The section number (`N` or `N.M`) at the start of `s`, and its length in bytes. A dot ends
/// the number unless a digit follows it (so `algorithms.md 9.` at the end of a sentence is 9).
fn section_number(s: &str) -> Option<(String, usize)> {
    let b = s.as_bytes();
    let digits = |from: usize| b[from..].iter().take_while(|c| c.is_ascii_digit()).count();
    let n = digits(0);
    if n == 0 {
        return None;
    }
    let mut end = n;
    if b.get(end) == Some(&b'.') && b.get(end + 1).is_some_and(u8::is_ascii_digit) {
        end += 1 + digits(end + 1);
    }
    Some((s[..end].to_string(), end))
}

/// The citations of docs/algorithms.md in `text`, as (line, section): each `algorithms.md`
/// followed by a section number (`algorithms.md 4.6`, also after `section`, `sections` or `§`),
/// and the numbers that continue its list (`algorithms.md 13.4, 13.5`, `algorithms.md 8 and
/// 14.1`, the two ends of `algorithms.md 4.7-4.9`). An `algorithms.md` followed by no number
/// gives an empty section: a citation must say which section it means.
fn citations(text: &str) -> Vec<(usize, String)> {
    const NAME: &str = "algorithms.md";
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut from = 0;
        while let Some(at) = line[from..].find(NAME) {
            let mut rest = &line[from + at + NAME.len()..];
            from += at + NAME.len();
            rest = rest.trim_start();
            for word in ["sections", "section", "§"] {
                if let Some(r) = rest.strip_prefix(word) {
                    rest = r.trim_start();
                    break;
                }
            }
            let Some((first, len)) = section_number(rest) else {
                out.push((n + 1, String::new()));
                continue;
            };
            out.push((n + 1, first));
            rest = &rest[len..];
            // The list goes on while a separator is followed by another number.
            while let Some((number, after)) = [", ", " and ", "-"].iter().find_map(|sep| {
                let r = rest.strip_prefix(sep)?;
                let (number, len) = section_number(r)?;
                Some((number, &r[len..]))
            }) {
                out.push((n + 1, number));
                rest = after;
            }
        }
    }
    out
}

/// The files whose text may cite docs/algorithms.md: sources, tests, benches and scripts, the
/// README and the other docs (not this file, whose comments show the forms, nor binary inputs).
fn citing_files() -> Vec<PathBuf> {
    let root = crate::common::root();
    let mut files = vec![root.join("README.md")];
    let mut stack: Vec<PathBuf> = ["src", "tests", "benches", "scripts", "docs"]
        .iter()
        .map(|d| root.join(d))
        .collect();
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|x| ["rs", "md", "sh", "py"].iter().any(|e| x == *e))
                && !p.ends_with("docs/algorithms.md")
                && !p.ends_with("tests/it/layout.rs")
            {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

/// Every `algorithms.md N` or `algorithms.md N.M` cited in the sources, tests, benches,
/// scripts and docs is a heading of docs/algorithms.md, so that a reader finds what the
/// comment refers to. Fails with the file, the line and the missing section.
#[test]
fn algorithms_md_citations_are_headings() {
    let root = crate::common::root();
    let doc = std::fs::read_to_string(root.join("docs/algorithms.md")).expect("docs/algorithms.md");
    let sections = algorithm_sections(&doc);
    assert!(
        sections.len() > 40,
        "found only {} sections",
        sections.len()
    );
    let mut cited = 0;
    let mut wrong = Vec::new();
    for path in citing_files() {
        let text = std::fs::read_to_string(&path).expect("readable");
        let rel = path
            .strip_prefix(&root)
            .unwrap_or(&path)
            .display()
            .to_string();
        for (line, section) in citations(&text) {
            cited += 1;
            if section.is_empty() {
                wrong.push(format!(
                    "{rel}:{line}: cites algorithms.md without a section number"
                ));
            } else if !sections.contains(&section) {
                wrong.push(format!(
                    "{rel}:{line}: algorithms.md {section} is not a heading"
                ));
            }
        }
    }
    assert!(cited > 100, "found only {cited} citations");
    assert!(
        wrong.is_empty(),
        "citations of docs/algorithms.md that name no section:\n{}",
        wrong.join("\n")
    );
}

/// The citation checker reads every form the sources use, and reports a wrong number.
#[test]
fn the_citation_check_catches_a_wrong_section() {
    let doc = "# T\n## 4. CNC\n### 4.6 Avg\n### 4.7 Hex\n### 4.9 Del\n## 9. Auto\n### 9.5 Ev\n\
               #### 9.5.1 deeper\n## Notes\n### 13.4 Torus\n### 13.5 Goursat\n";
    let sections = algorithm_sections(doc);
    let want = ["4", "4.6", "4.7", "4.9", "9", "9.5", "13.4", "13.5"];
    assert_eq!(sections, want.iter().map(|s| s.to_string()).collect());
    let text = "// x (algorithms.md 4.6) and algorithms.md 13.4, 13.5: y\n\
                // algorithms.md 4.7-4.9, L = 2; algorithms.md §9 and algorithms.md section 9.5.\n\
                // algorithms.md 9.5's figure; the sign of algorithms.md's convention\n\
                // algorithms.md 4 and 9.5 quotes 0.4993-0.5005; algorithms.md 4.66 algorithms.md 7.1";
    let found = citations(text);
    let want = [
        (1, "4.6"),
        (1, "13.4"),
        (1, "13.5"),
        (2, "4.7"),
        (2, "4.9"),
        (2, "9"),
        (2, "9.5"),
        (3, "9.5"),
        (3, ""),
        (4, "4"),
        (4, "9.5"),
        (4, "4.66"),
        (4, "7.1"),
    ];
    assert_eq!(found, want.map(|(l, s)| (l, s.to_string())));
    let missing: Vec<&str> = found
        .iter()
        .filter(|(_, s)| !sections.contains(s))
        .map(|(_, s)| s.as_str())
        .collect();
    assert_eq!(missing, ["", "4.66", "7.1"]);
}
