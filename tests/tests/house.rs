//! House rules of the codebase, read from its own source as syntax trees (`syn`):
//!
//! - in `engine/src`, only `gpu/` and `render/` name Vulkan (`ash`, `vk::`); `graph/` and the
//!   frame's builders stay Vulkan-free;
//! - no import cycle among the modules of `engine/src/hybrid/` (its folders `frame/` and `gpu/`
//!   each one module), nor among the files inside `hybrid/gpu/`;
//! - no function of any crate takes a tuple as a parameter: a group of parameters is a named
//!   struct or separate parameters (a trait's own signature, as `From<(A, B)>`, is the trait's).
//!
//! Imports are resolved as rustc does for the paths this codebase writes: `crate::`, `super::`,
//! `self::` and child modules, through `pub use` re-exports (named and glob) to the module that
//! defines the item.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use lensmap_tests::source::{rust_files, workspace};

use quote::ToTokens;
use syn::visit::Visit;

fn parse(path: &Path) -> syn::File {
    let text = std::fs::read_to_string(path).expect("readable source");
    syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn line(span: proc_macro2::Span) -> usize {
    span.start().line
}

/// `file:line` relative to the workspace.
fn place(file: &Path, line: usize) -> String {
    let root = workspace();
    format!(
        "{}:{line}",
        file.strip_prefix(&root).unwrap_or(file).display()
    )
}

/// A module path from the crate root, e.g. `["hybrid", "gpu", "tracer"]`.
type ModPath = Vec<String>;

/// The module a file of crate source folder `src` holds.
fn module_path(src: &Path, file: &Path) -> ModPath {
    let relative = file.strip_prefix(src).expect("a file of the crate");
    let mut parts: ModPath = relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().expect("a file name");
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_owned());
    }
    parts
}

/// The paths a use tree brings in, each with the name it is known by (`None` for a glob, whose
/// path is the module globbed). `self` in a group names the group's module.
fn flatten_use(
    tree: &syn::UseTree,
    prefix: &mut Vec<String>,
    out: &mut Vec<(ModPath, Option<String>)>,
) {
    match tree {
        syn::UseTree::Path(path) => {
            prefix.push(path.ident.to_string());
            flatten_use(&path.tree, prefix, out);
            prefix.pop();
        }
        syn::UseTree::Name(name) if name.ident == "self" => {
            let known = prefix.last().cloned();
            out.push((prefix.clone(), known));
        }
        syn::UseTree::Name(name) => {
            let mut path = prefix.clone();
            path.push(name.ident.to_string());
            out.push((path, Some(name.ident.to_string())));
        }
        syn::UseTree::Rename(rename) => {
            let mut path = prefix.clone();
            path.push(rename.ident.to_string());
            out.push((path, Some(rename.rename.to_string())));
        }
        syn::UseTree::Glob(_) => out.push((prefix.clone(), None)),
        syn::UseTree::Group(group) => {
            for tree in &group.items {
                flatten_use(tree, prefix, out);
            }
        }
    }
}

/// One module file of a crate: where it sits, its child modules, what it defines and what it
/// re-exports.
struct Module {
    file: PathBuf,
    here: ModPath,
    ast: syn::File,
    children: BTreeSet<String>,
    defined: BTreeSet<String>,
    /// `pub use` names and the absolute paths they stand for.
    reexports: BTreeMap<String, ModPath>,
    /// `pub use …::*` modules.
    globs: Vec<ModPath>,
}

impl Module {
    /// `segments` as a path from the crate root, when it starts in this crate.
    fn absolute(&self, segments: &[String]) -> Option<ModPath> {
        let first = segments.first()?;
        match first.as_str() {
            "crate" => Some(segments[1..].to_vec()),
            "self" => Some([&self.here[..], &segments[1..]].concat()),
            "super" => {
                let ups = segments.iter().take_while(|s| *s == "super").count();
                let base = self.here.len().checked_sub(ups)?;
                Some([&self.here[..base], &segments[ups..]].concat())
            }
            name if self.children.contains(name) => Some([&self.here[..], segments].concat()),
            _ => None,
        }
    }
}

/// Every module file of the crate whose root folder is `src`.
fn crate_modules(src: &Path) -> BTreeMap<ModPath, Module> {
    let mut modules = BTreeMap::new();
    for file in rust_files(src) {
        let ast = parse(&file);
        let here = module_path(src, &file);
        let mut module = Module {
            file,
            here,
            ast,
            children: BTreeSet::new(),
            defined: BTreeSet::new(),
            reexports: BTreeMap::new(),
            globs: Vec::new(),
        };
        let mut uses = Vec::new();
        for item in &module.ast.items {
            let ident = match item {
                syn::Item::Mod(m) => {
                    if m.content.is_none() {
                        module.children.insert(m.ident.to_string());
                    }
                    Some(&m.ident)
                }
                syn::Item::Fn(f) => Some(&f.sig.ident),
                syn::Item::Struct(s) => Some(&s.ident),
                syn::Item::Enum(e) => Some(&e.ident),
                syn::Item::Const(c) => Some(&c.ident),
                syn::Item::Static(s) => Some(&s.ident),
                syn::Item::Type(t) => Some(&t.ident),
                syn::Item::Trait(t) => Some(&t.ident),
                syn::Item::Union(u) => Some(&u.ident),
                syn::Item::Use(u) if !matches!(u.vis, syn::Visibility::Inherited) => {
                    flatten_use(&u.tree, &mut Vec::new(), &mut uses);
                    None
                }
                _ => None,
            };
            if let Some(ident) = ident {
                module.defined.insert(ident.to_string());
            }
        }
        for (path, name) in uses {
            let Some(absolute) = module.absolute(&path) else {
                continue;
            };
            match name {
                Some(name) => {
                    module.reexports.insert(name, absolute);
                }
                None => module.globs.push(absolute),
            }
        }
        modules.insert(module.here.clone(), module);
    }
    modules
}

/// The module that defines what absolute path `path` names: the longest module prefix, followed
/// through that module's re-exports.
fn defining_module(
    modules: &BTreeMap<ModPath, Module>,
    path: &[String],
    depth: usize,
) -> Option<ModPath> {
    let prefix = (0..=path.len())
        .rev()
        .find(|&n| modules.contains_key(&path[..n]))?;
    let module = &modules[&path[..prefix]];
    let Some(name) = path.get(prefix) else {
        return Some(module.here.clone());
    };
    if depth == 0 || module.defined.contains(name) {
        return Some(module.here.clone());
    }
    if let Some(target) = module.reexports.get(name) {
        let followed = [&target[..], &path[prefix + 1..]].concat();
        return defining_module(modules, &followed, depth - 1).or(Some(module.here.clone()));
    }
    for glob in &module.globs {
        let followed = [&glob[..], &path[prefix..]].concat();
        if let Some(found) = defining_module(modules, &followed, depth - 1)
            && found != *glob
        {
            return Some(found);
        }
        if modules.get(glob).is_some_and(|g| g.defined.contains(name)) {
            return Some(glob.clone());
        }
    }
    Some(module.here.clone())
}

/// Every path a module's file writes (imports, types, expressions; inline modules, the tests',
/// left out), with its line.
struct PathsWritten {
    found: Vec<(Vec<String>, usize)>,
}

impl<'ast> Visit<'ast> for PathsWritten {
    fn visit_item_mod(&mut self, item: &'ast syn::ItemMod) {
        if item.content.is_none() {
            syn::visit::visit_item_mod(self, item);
        }
    }

    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        let mut paths = Vec::new();
        flatten_use(&item.tree, &mut Vec::new(), &mut paths);
        let at = line(item.use_token.span);
        self.found
            .extend(paths.into_iter().map(|(path, _)| (path, at)));
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let segments: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
        if segments.len() >= 2 {
            let at = path.segments.first().map_or(0, |s| line(s.ident.span()));
            self.found.push((segments, at));
        }
        syn::visit::visit_path(self, path);
    }
}

/// The imports among the modules of the crate at `src`, collapsed by `node` (modules it maps to
/// `None` are left out): each edge with the first place that makes it.
fn import_graph(
    src: &Path,
    node: impl Fn(&[String]) -> Option<String>,
) -> BTreeMap<(String, String), String> {
    let modules = crate_modules(src);
    let mut edges = BTreeMap::new();
    for module in modules.values() {
        let Some(from) = node(&module.here) else {
            continue;
        };
        let mut written = PathsWritten { found: Vec::new() };
        written.visit_file(&module.ast);
        for (path, at) in written.found {
            let Some(absolute) = module.absolute(&path) else {
                continue;
            };
            let Some(target) = defining_module(&modules, &absolute, 8) else {
                continue;
            };
            if let Some(to) = node(&target)
                && to != from
            {
                edges
                    .entry((from.clone(), to))
                    .or_insert_with(|| place(&module.file, at));
            }
        }
    }
    edges
}

/// A cycle of `edges`, as the nodes in order with the place of each step, if there is one.
fn find_cycle(edges: &BTreeMap<(String, String), String>) -> Option<Vec<String>> {
    let mut next: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (from, to) in edges.keys() {
        next.entry(from).or_default().push(to);
    }
    // Depth-first search with the path on a stack: an edge back into the stack closes a cycle.
    fn walk<'a>(
        node: &'a str,
        next: &BTreeMap<&'a str, Vec<&'a str>>,
        stack: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<&'a str>> {
        if let Some(start) = stack.iter().position(|n| *n == node) {
            let mut cycle = stack[start..].to_vec();
            cycle.push(node);
            return Some(cycle);
        }
        if !done.insert(node) {
            return None;
        }
        stack.push(node);
        for to in next.get(node).into_iter().flatten() {
            if let Some(cycle) = walk(to, next, stack, done) {
                return Some(cycle);
            }
        }
        stack.pop();
        None
    }
    let mut done = BTreeSet::new();
    for &start in next.keys() {
        if let Some(cycle) = walk(start, &next, &mut Vec::new(), &mut done) {
            return Some(
                cycle
                    .windows(2)
                    .map(|pair| {
                        let at = &edges[&(pair[0].to_owned(), pair[1].to_owned())];
                        format!("{} → {} ({at})", pair[0], pair[1])
                    })
                    .collect(),
            );
        }
    }
    None
}

fn engine_src() -> PathBuf {
    workspace().join("engine/src")
}

/// `hybrid/`'s modules, `frame/` and `gpu/` each one.
fn hybrid_module(path: &[String]) -> Option<String> {
    match path {
        [first, second, ..] if first == "hybrid" => Some(second.clone()),
        _ => None,
    }
}

/// The files inside `hybrid/gpu/` (its `mod.rs`, which only declares and re-exports them, left
/// out).
fn gpu_file(path: &[String]) -> Option<String> {
    match path {
        [a, b, file, ..] if a == "hybrid" && b == "gpu" => Some(file.clone()),
        _ => None,
    }
}

#[test]
fn the_import_graph_sees_the_imports_the_code_writes() {
    // Known imports of today's code, through each form the resolver follows: `super::` between
    // siblings, `crate::` paths, re-exports of `hybrid/mod.rs`, and a child module's name.
    let hybrid = import_graph(&engine_src(), hybrid_module);
    for (from, to) in [
        ("frame", "scene"),
        ("frame", "paths"),
        ("scene", "sky"),
        ("gpu", "paths"),
    ] {
        assert!(
            hybrid.contains_key(&(from.to_owned(), to.to_owned())),
            "hybrid/{from} imports hybrid/{to}; the graph has {:?}",
            hybrid.keys().collect::<Vec<_>>()
        );
    }
    let gpu = import_graph(&engine_src(), gpu_file);
    for (from, to) in [
        ("tessellate", "tracer"),
        ("tracer", "walk"),
        ("resident", "work"),
    ] {
        assert!(
            gpu.contains_key(&(from.to_owned(), to.to_owned())),
            "hybrid/gpu/{from} imports hybrid/gpu/{to}; the graph has {:?}",
            gpu.keys().collect::<Vec<_>>()
        );
    }
    // And the cycle finder finds a cycle where there is one.
    let mut with_cycle = hybrid.clone();
    with_cycle.insert(("scene".into(), "frame".into()), "a test".into());
    let cycle = find_cycle(&with_cycle).expect("a cycle");
    assert!(
        cycle.iter().any(|step| step.starts_with("scene → frame")),
        "{cycle:?}"
    );
}

#[test]
fn the_modules_of_hybrid_import_one_another_without_a_cycle() {
    let hybrid = import_graph(&engine_src(), hybrid_module);
    if let Some(cycle) = find_cycle(&hybrid) {
        panic!(
            "an import cycle among hybrid/'s modules:\n  {}",
            cycle.join("\n  ")
        );
    }
    let gpu = import_graph(&engine_src(), gpu_file);
    if let Some(cycle) = find_cycle(&gpu) {
        panic!(
            "an import cycle among hybrid/gpu/'s files:\n  {}",
            cycle.join("\n  ")
        );
    }
}

/// Paths that name Vulkan: `ash::…`, `vk::…` (and a `use ash…`).
struct VulkanPaths {
    found: Vec<(String, usize)>,
}

impl<'ast> Visit<'ast> for VulkanPaths {
    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        let mut paths = Vec::new();
        flatten_use(&item.tree, &mut Vec::new(), &mut paths);
        for (path, _) in paths {
            if path.first().is_some_and(|s| s == "ash") {
                self.found
                    .push((path.join("::"), line(item.use_token.span)));
            }
        }
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        if let Some(first) = path.segments.first()
            && (first.ident == "ash" || first.ident == "vk")
        {
            let text: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
            self.found.push((text.join("::"), line(first.ident.span())));
        }
        syn::visit::visit_path(self, path);
    }
}

#[test]
fn only_gpu_and_render_name_vulkan_in_the_engine() {
    let src = engine_src();
    let mut found = Vec::new();
    let mut read = 0;
    for file in rust_files(&src) {
        let relative = file.strip_prefix(&src).expect("under src");
        if relative.starts_with("gpu") || relative.starts_with("render") {
            continue;
        }
        read += 1;
        let mut paths = VulkanPaths { found: Vec::new() };
        paths.visit_file(&parse(&file));
        found.extend(
            paths
                .found
                .into_iter()
                .map(|(path, at)| format!("{}: {path}", place(&file, at))),
        );
    }
    assert!(
        read > 50,
        "read {read} files of engine/src outside gpu/ and render/"
    );
    assert!(
        found.is_empty(),
        "Vulkan named outside engine/src/gpu and engine/src/render (move the call into gpu/ or \
         render/ behind a function of theirs):\n  {}",
        found.join("\n  ")
    );
}

#[test]
fn the_vulkan_finder_sees_ash_and_vk_paths() {
    let file: syn::File = syn::parse_str(
        "use ash::vk; fn f(b: vk::Buffer) -> u32 { let x = ash::Entry::linked(); 0 }",
    )
    .unwrap();
    let mut paths = VulkanPaths { found: Vec::new() };
    paths.visit_file(&file);
    let names: Vec<&str> = paths.found.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(names, ["ash::vk", "vk::Buffer", "ash::Entry::linked"]);
}

/// Functions with a tuple among their parameters, outside trait impls (whose signatures are the
/// trait's).
struct TupleParameters {
    found: Vec<(String, usize)>,
}

impl TupleParameters {
    fn check(&mut self, sig: &syn::Signature) {
        for input in &sig.inputs {
            let syn::FnArg::Typed(typed) = input else {
                continue;
            };
            let mut ty = &*typed.ty;
            loop {
                ty = match ty {
                    syn::Type::Reference(r) => &r.elem,
                    syn::Type::Paren(p) => &p.elem,
                    syn::Type::Group(g) => &g.elem,
                    _ => break,
                };
            }
            if let syn::Type::Tuple(tuple) = ty
                && tuple.elems.len() >= 2
            {
                let pattern = typed.pat.to_token_stream().to_string();
                self.found.push((
                    format!("fn {}: {pattern}", sig.ident),
                    line(sig.ident.span()),
                ));
            }
        }
    }
}

impl<'ast> Visit<'ast> for TupleParameters {
    fn visit_item_impl(&mut self, item: &'ast syn::ItemImpl) {
        if item.trait_.is_none() {
            syn::visit::visit_item_impl(self, item);
        }
    }

    fn visit_signature(&mut self, sig: &'ast syn::Signature) {
        self.check(sig);
        syn::visit::visit_signature(self, sig);
    }
}

#[test]
fn no_function_takes_a_tuple_of_parameters() {
    let root = workspace();
    let mut found = Vec::new();
    let mut read = 0;
    for folder in ["engine", "baker", "tools", "tests", "shaders"] {
        for file in rust_files(&root.join(folder)) {
            read += 1;
            let mut tuples = TupleParameters { found: Vec::new() };
            tuples.visit_file(&parse(&file));
            found.extend(
                tuples
                    .found
                    .into_iter()
                    .map(|(what, at)| format!("{}: {what}", place(&file, at))),
            );
        }
    }
    assert!(read > 200, "read {read} files");
    assert!(
        found.is_empty(),
        "tuples as parameters (give the group a named struct, or pass the parts separately):\n  {}",
        found.join("\n  ")
    );
}

#[test]
fn the_tuple_finder_sees_tuple_parameters_and_not_trait_impls() {
    let file: syn::File = syn::parse_str(
        "fn a((x, y): (u32, u32)) {} \
         fn b(size: &(u32, bool)) {} \
         fn c(unit: (), one: (u32,)) {} \
         impl From<(A, B)> for C { fn from((a, b): (A, B)) -> C { C } } \
         impl C { fn d(&self, p: (f64, f64)) {} }",
    )
    .unwrap();
    let mut tuples = TupleParameters { found: Vec::new() };
    tuples.visit_file(&file);
    let names: Vec<&str> = tuples.found.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(names, ["fn a: (x , y)", "fn b: size", "fn d: p"]);
}
