//! The layering ARCHITECTURE.md describes, checked on the source: modules import only from
//! layers below theirs or from their own group, only the CPU backend and the backend chooser
//! (device.rs) reach into `src/cpu`, and no two modules import each other, directly or round
//! a cycle. A module is a file under src/ (`init::rigid` for src/init/rigid.rs) or, outside
//! the stage groups, a top-level directory (`gpu` for src/gpu/run.rs). Test modules
//! (`#[cfg(test)]`) are left out: a unit test may use the CPU backend to run what it tests.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Modules that may import `crate::cpu`: the CPU backend itself, the module that opens a
/// backend for every door, and the phantom, which is made on the host so that its bytes do not
/// depend on the caller's device.
const MAY_USE_CPU: &[&str] = &["cpu", "device", "phantom"];

/// The layers, bottom up: the kernel vocabulary (ABI structs, the Backend trait, shared types
/// and settings), the two backends, operations the stages share, files on disk, the stages,
/// whole registrations, reporting, the one registration entry every door calls, the command
/// line. A module imports from lower layers and from its own group only (the vocabulary's
/// modules from each other).
const LAYERS: &[&[&str]] = &[
    &[
        "abi", "backend", "check", "error", "labels", "levels", "progress", "sample", "shaders",
        "volume",
    ],
    &["cpu", "gpu"],
    &["device", "images", "joints"],
    &["io"],
    &["init", "nonrigid", "phantom"],
    &["finish"],
    &["pipeline"],
    &["report"],
    &["registration"],
    &["jobs"],
    &["cli"],
];

/// Directories under src/ whose files are modules of their own (the stage groups); the other
/// directories are one module each.
const GROUPS: &[&str] = &[
    "images", "joints", "init", "nonrigid", "pipeline", "report", "jobs",
];

/// The module of a file under src/ ("init::rigid" for src/init/rigid.rs, "report" for
/// src/report/mod.rs, "gpu" for src/gpu/run.rs), None for the crate roots.
fn module_of(relative: &Path) -> Option<String> {
    let parts: Vec<String> = relative
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    let top = parts[0].clone();
    if top == "lib" || top == "main" {
        return None;
    }
    match parts.get(1) {
        Some(inner) if GROUPS.contains(&top.as_str()) && inner != "mod" => {
            Some(format!("{top}::{inner}"))
        }
        _ => Some(top),
    }
}

/// The group of a module ("init" for "init::rigid").
fn group_of(module: &str) -> &str {
    module.split("::").next().unwrap()
}

/// The layer a module's group sits in.
fn layer_of(module: &str) -> usize {
    let group = group_of(module);
    LAYERS
        .iter()
        .position(|layer| layer.contains(&group))
        .unwrap_or_else(|| panic!("module {module} is in no layer: add it to LAYERS"))
}

/// The file's code without its `#[cfg(test)]` module (which, by convention here, ends a file).
fn code_of(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]") {
        Some(at) => text[..at].to_string(),
        None => text,
    }
}

/// The modules a path names, from what follows `crate::` ("init::rigid" for
/// `init::rigid::Rigid`, "io" for `io::nifti`), nested groups (`init::{rigid, vsd}`) included.
fn modules_named(path: &str, out: &mut BTreeSet<String>) {
    let head: String = path
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    if head.is_empty() {
        return;
    }
    let rest = path[head.len()..].trim_start();
    let Some(rest) = rest
        .strip_prefix("::")
        .filter(|_| GROUPS.contains(&head.as_str()))
    else {
        out.insert(head);
        return;
    };
    let rest = rest.trim_start();
    let inner: Vec<&str> = match rest.strip_prefix('{') {
        Some(group) => split_top_level(&group[..closing_brace(group)]),
        None => vec![rest],
    };
    for item in inner {
        let name: String = item
            .trim()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        match name.as_str() {
            "" | "self" => out.insert(head.clone()),
            // An item of the group's own mod.rs (report::Report) rather than a module.
            _ if name.starts_with(char::is_uppercase) => out.insert(head.clone()),
            _ => out.insert(format!("{head}::{name}")),
        };
    }
}

/// Where the brace group that `text` opens inside closes (the index of its `}`).
fn closing_brace(text: &str) -> usize {
    let mut depth = 1;
    for (at, c) in text.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 1 => return at,
            '}' => depth -= 1,
            _ => {}
        }
    }
    text.len()
}

/// `text` split at the commas outside braces.
fn split_top_level(text: &str) -> Vec<&str> {
    let (mut items, mut depth, mut start) = (Vec::new(), 0, 0);
    for (at, c) in text.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&text[start..at]);
                start = at + 1;
            }
            _ => {}
        }
    }
    items.push(&text[start..]);
    items
}

/// The modules a file's code names as `crate::…`, including inside `use crate::{..}`.
fn imports(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (at, _) in code.match_indices("crate::") {
        let rest = &code[at + "crate::".len()..];
        match rest.strip_prefix('{') {
            Some(group) => {
                for item in split_top_level(&group[..closing_brace(group)]) {
                    modules_named(item.trim(), &mut out);
                }
            }
            None => modules_named(rest, &mut out),
        }
    }
    out
}

/// Module → the other modules it imports.
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
fn modules_import_only_from_lower_layers_or_their_own_group() {
    let mut offences = Vec::new();
    for (module, deps) in graph() {
        for dep in deps {
            let upward = layer_of(&dep) >= layer_of(&module);
            // The vocabulary's modules build on each other (abi on volume, volume on error).
            let within = group_of(&dep) == group_of(&module) || layer_of(&module) == 0;
            if upward && !within {
                offences.push(format!("{module} → {dep}"));
            }
        }
    }
    assert!(
        offences.is_empty(),
        "imports from the same layer or above (tests/layers.rs LAYERS): {offences:?}"
    );
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

/// The doors (the command line, the Python package) open a backend through the device chooser
/// only: none names a backend's type, so every door runs on the device the user asked for.
#[test]
fn the_command_line_and_the_python_package_name_no_backend() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut offences = Vec::new();
    for folder in ["src/cli", "python/src"] {
        for entry in std::fs::read_dir(root.join(folder)).unwrap() {
            let path = entry.unwrap().path();
            let code = code_of(&path);
            let code: Vec<&str> = (code.lines())
                .filter(|l| !l.trim_start().starts_with("//"))
                .collect();
            for name in ["CpuBackend", "GpuBackend", "GpuContext"] {
                if code.iter().any(|l| l.contains(name)) {
                    offences.push(format!("{} names {name}", path.display()));
                }
            }
        }
    }
    assert!(
        offences.is_empty(),
        "open backends with posereg::device::open_backend: {offences:?}"
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
    // The parser finds plain, grouped and nested imports, a stage group's modules and its
    // mod.rs items, and ignores test modules.
    let code = "use crate::abi::X;\nuse crate::{gpu::Y, volume, init::{rigid, vsd::Z}};\n\
                fn f() { crate::io::g(); crate::nonrigid::adaptive::h(); }\n\
                use crate::report::Report;\n\
                #[cfg(test)]\nmod tests { use crate::cpu::CpuBackend; }";
    let dir = std::env::temp_dir().join(format!("posereg-layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("x.rs");
    std::fs::write(&file, code).unwrap();
    let found = imports(&code_of(&file));
    std::fs::remove_dir_all(&dir).unwrap();
    let want: BTreeSet<String> = [
        "abi",
        "gpu",
        "volume",
        "init::rigid",
        "init::vsd",
        "io",
        "nonrigid::adaptive",
        "report",
    ]
    .map(String::from)
    .into();
    assert_eq!(found, want);
    let module = |path: &str| module_of(Path::new(path));
    assert_eq!(module("init/rigid.rs").as_deref(), Some("init::rigid"));
    assert_eq!(module("report/mod.rs").as_deref(), Some("report"));
    assert_eq!(
        module("report/quicklook/draw.rs").as_deref(),
        Some("report::quicklook")
    );
    assert_eq!(module("gpu/run.rs").as_deref(), Some("gpu"));
    assert_eq!(module("lib.rs"), None);
    assert!(layer_of("cli") > layer_of("init::rigid") && layer_of("init") > layer_of("abi"));
}
