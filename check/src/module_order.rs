//! A crate's modules import one another in one order, with no cycle: [`check`] reads every source
//! file of a crate, collects the modules each one names through `crate::` paths (in `use` lines
//! and in code, tests included; comments and doc links are not imports), and lists every module
//! that names one not before it in the crate's order. The generator and the trainer each hold
//! their order in a unit test that calls it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// [`check`] of the crate at `manifest_dir` (its `src/`), the files that are not modules of the
/// graph being the crate root, a binary's `main.rs` and the test holding the order,
/// `module_order.rs`; panics with every import against `order`.
pub fn assert_crate_order(manifest_dir: &str, order: &[&str]) {
    let src = Path::new(manifest_dir).join("src");
    if let Err(wrong) = check(&src, order, &["lib.rs", "main.rs", "module_order.rs"]) {
        panic!("the module order (src/module_order.rs) is broken:\n{wrong}");
    }
}

/// Every import against `order` among the top-level modules of the crate whose sources are in
/// `src` (`skip`: files of `src` that are not modules of the graph: the crate root, a binary, the
/// test holding the order); also a module missing from `order`, or one `lib.rs` does not declare.
pub fn check(src: &Path, order: &[&str], skip: &[&str]) -> Result<(), String> {
    let graph = import_graph(src, skip);
    let declared: BTreeSet<String> = code_only(&std::fs::read_to_string(src.join("lib.rs")).map_err(|e| format!("lib.rs: {e}"))?)
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod ").or_else(|| l.trim().strip_prefix("mod "))?.strip_suffix(';').map(str::to_string))
        .filter(|m| !skip.contains(&format!("{m}.rs").as_str()))
        .collect();
    let ordered: BTreeSet<String> = order.iter().map(|m| m.to_string()).collect();
    let mut wrong = Vec::new();
    if declared != ordered {
        wrong.push(format!("lib.rs declares {declared:?}, the order lists {ordered:?}"));
    }
    let position = |m: &str| order.iter().position(|o| *o == m);
    for (module, names) in &graph {
        let Some(at) = position(module) else {
            wrong.push(format!("src/{module} is not in the order"));
            continue;
        };
        for name in names {
            match position(name) {
                Some(p) if p < at => {}
                Some(_) => wrong.push(format!("{module} imports {name}, which comes after it")),
                None => wrong.push(format!("{module} names crate::{name}, not a module in the order")),
            }
        }
    }
    if wrong.is_empty() { Ok(()) } else { Err(wrong.join("\n")) }
}

/// `text` with comments, string literals and char literals each replaced by a space.
fn code_only(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < chars.len() {
        match skipped_len(&chars[i..], i.checked_sub(1).map(|p| chars[p])) {
            0 => {
                out.push(chars[i]);
                i += 1;
            }
            skip => {
                out.push(' ');
                i += skip;
            }
        }
    }
    out
}

/// The length of the comment or literal `rest` starts with (0: code). `before` is the character
/// before it (an identifier's `r` is no raw string).
fn skipped_len(rest: &[char], before: Option<char>) -> usize {
    let at = |k: usize| rest.get(k).copied();
    let find = |from: usize, end: &[char]| (from..rest.len()).find(|&k| rest[k..].starts_with(end)).map_or(rest.len(), |k| k + end.len());
    match (at(0), at(1)) {
        (Some('/'), Some('/')) => find(0, &['\n']),
        // Nested block comments are rare enough to leave out.
        (Some('/'), Some('*')) => find(2, &['*', '/']),
        (Some('r'), Some('"' | '#')) if !before.is_some_and(is_ident) => {
            // A raw string: r"…" or r#"…"#.
            let hashes = rest[1..].iter().take_while(|&&h| h == '#').count();
            if at(1 + hashes) != Some('"') {
                return 0;
            }
            let end: Vec<char> = std::iter::once('"').chain(std::iter::repeat_n('#', hashes)).collect();
            find(2 + hashes, &end)
        }
        (Some('"'), _) => {
            let mut k = 1;
            while k < rest.len() && rest[k] != '"' {
                k += if rest[k] == '\\' { 2 } else { 1 };
            }
            k + 1
        }
        // A char literal ('x', '\n'); a lifetime ('a) has no closing quote after one character.
        (Some('\''), Some('\\')) => find(3, &['\'']),
        (Some('\''), Some(_)) if at(2) == Some('\'') => 3,
        _ => 0,
    }
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The top-level modules a piece of code names: `crate::x::…` and `crate::{x::…, y}`.
fn named_modules(code: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for (at, _) in code.match_indices("crate::") {
        if code[..at].chars().next_back().is_some_and(|p| is_ident(p) || p == '$') {
            continue;
        }
        let rest = code[at + "crate::".len()..].trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            // The first path segment of each item of the group, at the group's own depth.
            let (mut depth, mut item_start) = (0, true);
            for (k, ch) in group.char_indices() {
                match ch {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => item_start = true,
                    c if item_start && is_ident(c) => {
                        let name: String = group[k..].chars().take_while(|&c| is_ident(c)).collect();
                        found.insert(name);
                        item_start = false;
                    }
                    _ => {}
                }
            }
        } else {
            let name: String = rest.chars().take_while(|&c| is_ident(c)).collect();
            if !name.is_empty() {
                found.insert(name);
            }
        }
    }
    found
}

/// Module → the other modules its files name, over every `.rs` file under `src`.
fn import_graph(src: &Path, skip: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut dirs = vec![src.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
                continue;
            }
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.extension().is_none_or(|e| e != "rs") || (dir == src && skip.contains(&name.as_str())) {
                continue;
            }
            let top = path.strip_prefix(src).unwrap().components().next().unwrap();
            let module = top.as_os_str().to_string_lossy().trim_end_matches(".rs").to_string();
            let names = named_modules(&code_only(&std::fs::read_to_string(&path).unwrap()));
            graph.entry(module.clone()).or_default().extend(names.into_iter().filter(|n| *n != module));
        }
    }
    graph
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scanner_sees_paths_and_skips_comments_and_strings() {
        let code = code_only(
            "use crate::data::Batch; // crate::eval\n/// [`crate::train`]\nlet s = \"crate::report\";\nlet c = '\"';\n\
             use crate::{model::{PoseNet, Variant}, loss};\nfn f<'a>(x: &'a crate::run::RunDir) -> $crate::bench {}\n",
        );
        let names: Vec<String> = named_modules(&code).into_iter().collect();
        assert_eq!(names, ["data", "loss", "model", "run"]);
    }

    #[test]
    fn an_import_against_the_order_is_named() {
        let src = std::env::temp_dir().join(format!("vt-check-order-{}", std::process::id()));
        std::fs::create_dir_all(src.join("b")).unwrap();
        std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod b;\n").unwrap();
        std::fs::write(src.join("a.rs"), "use crate::b::X; // crate::c in a comment\n").unwrap();
        std::fs::write(src.join("b").join("mod.rs"), "pub struct X; // crate::a\n").unwrap();
        assert_eq!(check(&src, &["b", "a"], &["lib.rs"]), Ok(()));
        let e = check(&src, &["a", "b"], &["lib.rs"]).unwrap_err();
        assert_eq!(e, "a imports b, which comes after it");
        std::fs::remove_dir_all(&src).unwrap();
    }
}
