//! The layering ARCHITECTURE.md describes, checked on the source: only the CPU backend, the
//! backend chooser (device.rs) and sample.rs's users below it reach into `src/cpu`, and no two
//! modules import each other, directly or round a cycle. Test modules (`#[cfg(test)]`) are
//! left out: a unit test may use the CPU backend to run what it tests.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Modules that may import `crate::cpu`: the CPU backend itself and the module that opens a
/// backend for the command line.
const MAY_USE_CPU: &[&str] = &["cpu", "device"];

/// The top-level module of a file under src/ ("gpu" for src/gpu/run.rs), None for the crate
/// roots.
fn module_of(relative: &Path) -> Option<String> {
    let first = relative.components().next()?.as_os_str().to_string_lossy();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// The file's code without its `#[cfg(test)]` module (which, by convention here, ends a file).
fn code_of(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]") {
        Some(at) => text[..at].to_string(),
        None => text,
    }
}

/// The top-level modules a file's code names as `crate::x`, including inside `use crate::{..}`.
fn imports(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (at, _) in code.match_indices("crate::") {
        let rest = &code[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..group.find('}').unwrap_or(group.len())];
            for item in inner.split(',') {
                let head = item.trim().split("::").next().unwrap_or("").trim();
                if !head.is_empty() {
                    out.insert(head.to_string());
                }
            }
        } else {
            let head: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !head.is_empty() {
                out.insert(head);
            }
        }
    }
    out
}

/// Module → the other top-level modules it imports.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let Some(module) = module_of(path.strip_prefix(&root).unwrap()) else {
                continue;
            };
            let mut deps = imports(&code_of(&path));
            deps.remove(&module);
            graph.entry(module).or_default().extend(deps);
        }
    }
    let modules: BTreeSet<String> = graph.keys().cloned().collect();
    for deps in graph.values_mut() {
        deps.retain(|d| modules.contains(d));
    }
    graph
}

#[test]
fn only_the_cpu_backend_and_the_backend_chooser_import_src_cpu() {
    let offenders: Vec<String> = graph()
        .into_iter()
        .filter(|(module, deps)| deps.contains("cpu") && !MAY_USE_CPU.contains(&module.as_str()))
        .map(|(module, _)| module)
        .collect();
    assert!(
        offenders.is_empty(),
        "these modules import src/cpu; stages reach kernels through the Backend: {offenders:?}"
    );
}

#[test]
fn no_module_imports_itself_round_a_cycle() {
    let graph = graph();
    // Depth-first search with colours: grey on the current path, black when finished.
    fn visit(
        module: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        grey: &mut Vec<String>,
        black: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = grey.iter().position(|m| m == module) {
            let mut cycle = grey[at..].to_vec();
            cycle.push(module.to_string());
            return Some(cycle);
        }
        if black.contains(module) {
            return None;
        }
        grey.push(module.to_string());
        for dep in &graph[module] {
            if let Some(cycle) = visit(dep, graph, grey, black) {
                return Some(cycle);
            }
        }
        grey.pop();
        black.insert(module.to_string());
        None
    }
    let (mut grey, mut black) = (Vec::new(), BTreeSet::new());
    for module in graph.keys() {
        if let Some(cycle) = visit(module, &graph, &mut grey, &mut black) {
            panic!("import cycle: {}", cycle.join(" → "));
        }
    }
}

#[test]
fn the_checks_see_imports_and_cycles() {
    // The parser finds plain, grouped and nested imports, and ignores test modules.
    let code = "use crate::abi::X;\nuse crate::{gpu::Y, volume};\nfn f() { crate::io::g(); }\n\
                #[cfg(test)]\nmod tests { use crate::cpu::CpuBackend; }";
    let dir = std::env::temp_dir().join(format!("posereg-layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("x.rs");
    std::fs::write(&file, code).unwrap();
    let found = imports(&code_of(&file));
    std::fs::remove_dir_all(&dir).unwrap();
    let want: BTreeSet<String> = ["abi", "gpu", "volume", "io"].map(String::from).into();
    assert_eq!(found, want);
}
