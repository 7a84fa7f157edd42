//! The library's modules use one another without a cycle, so that each part can be read
//! (and changed) with only what lies below it in mind: read from the sources, as the
//! paths they name (`crate::…`, `super::…`, `self::…`, and the items of `{…}` groups).
//! A module's use of its own ancestors or descendants does not count: a folder's
//! `mod.rs` and its files are one part.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Module path (`accel::wide8`) to source text, without comments and test modules.
fn modules() -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut dirs = vec![root.clone()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                // The command line is a crate of its own, on top of the library.
                if path != root.join("bin") {
                    dirs.push(path);
                }
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let rel = path.strip_prefix(&root).unwrap().with_extension("");
            let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
            if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
                parts.pop();
            }
            if parts.last().is_some_and(|p| p == "tests") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let mut code = String::new();
            let mut lines = text.lines().peekable();
            while let Some(line) = lines.next() {
                let t = line.trim_start();
                if t.starts_with("#[cfg(test)]")
                    && lines.peek().is_some_and(|l| l.trim_start().starts_with("mod tests {"))
                {
                    break; // test modules close their files
                }
                code.push_str(line.split("//").next().unwrap());
                code.push('\n');
            }
            out.insert(parts.join("::"), code);
        }
    }
    out
}

fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// The paths `code` names from `crate`, `super` or `self`, as segments from the
/// crate's root (`super` and `self` resolved against `module`).
fn paths(module: &str, code: &str) -> Vec<Vec<String>> {
    let here: Vec<String> = module.split("::").filter(|s| !s.is_empty()).map(String::from).collect();
    let mut out = Vec::new();
    for (at, _) in code.match_indices("::") {
        // Only where a path starts: `crate::`, `super::` or `self::` after a non-word.
        let start = code[..at].rfind(|c: char| !(c.is_alphanumeric() || c == '_')).map_or(0, |i| i + 1);
        let head = &code[start..at];
        let before = code[..start].chars().next_back();
        if !matches!(head, "crate" | "super" | "self") || before == Some(':') {
            continue;
        }
        let mut base = match head {
            "crate" => Vec::new(),
            "super" => here[..here.len().saturating_sub(1)].to_vec(),
            _ => here.clone(),
        };
        let mut rest = &code[at + 2..];
        loop {
            if let Some(group) = rest.strip_prefix('{') {
                // Each item of the group, by its first segment.
                let end = group.find('}').unwrap_or(group.len());
                for item in group[..end].split(',') {
                    let name = ident(item.trim());
                    if !name.is_empty() && name != "self" {
                        out.push([base.clone(), vec![name.to_owned()]].concat());
                    }
                }
                out.push(base);
                break;
            }
            let name = ident(rest);
            if name == "super" {
                base.pop();
            } else if !name.is_empty() {
                base.push(name.to_owned());
            }
            rest = &rest[name.len()..];
            match rest.strip_prefix("::") {
                Some(r) => rest = r,
                None => {
                    out.push(base);
                    break;
                }
            }
        }
    }
    out
}

/// The longest module among `known` that `path` starts with.
fn module_of(path: &[String], known: &BTreeMap<String, String>) -> Option<String> {
    (0..=path.len()).rev().map(|n| path[..n].join("::")).find(|m| known.contains_key(m))
}

fn related(a: &str, b: &str) -> bool {
    let inside = |outer: &str, inner: &str| outer.is_empty() || inner.starts_with(&format!("{outer}::"));
    a == b || inside(a, b) || inside(b, a)
}

#[test]
fn the_librarys_modules_form_no_cycle() {
    let modules = modules();
    assert!(modules.len() > 40 && modules.contains_key("accel::wide8"), "{:?}", modules.keys());
    let mut uses: BTreeMap<&str, BTreeSet<String>> = BTreeMap::new();
    for (module, code) in &modules {
        for path in paths(module, code) {
            if let Some(target) = module_of(&path, &modules).filter(|t| !related(module, t)) {
                uses.entry(module).or_default().insert(target);
            }
        }
    }
    // The reader sees real uses (a check that finds nothing would pass on anything).
    assert!(uses["integrator"].contains("accel"), "{uses:?}");
    assert!(uses["accel::mesh_bvh"].contains("accel::wide"), "{uses:?}");
    // A cycle is a module that can reach itself.
    let mut cycles = Vec::new();
    for start in uses.keys() {
        let mut stack = vec![(start.to_string(), vec![start.to_string()])];
        let mut seen = BTreeSet::new();
        while let Some((m, trail)) = stack.pop() {
            for next in uses.get(m.as_str()).into_iter().flatten() {
                if next == start {
                    cycles.push([trail.clone(), vec![next.clone()]].concat().join(" -> "));
                } else if seen.insert(next.clone()) {
                    stack.push((next.clone(), [trail.clone(), vec![next.clone()]].concat()));
                }
            }
        }
    }
    assert!(cycles.is_empty(), "modules that use each other in a cycle:\n{}", cycles.join("\n"));
}
