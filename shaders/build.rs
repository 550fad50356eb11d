//! Compiles every `wgsl/*.wgsl` file to SPIR-V with naga, validating it on the way, after pasting
//! in the shared files it names with `// #include "NAME"` (from `wgsl/include/`). A shader error
//! fails the build with the file, line and column (naga's own diagnostic), so a broken shader never
//! reaches run time. Each entry point becomes its own SPIR-V blob in `$OUT_DIR/<file>.<entry>.spv`.
//!
//! Entry points whose name ends in `_specialized` read WGSL `override` constants; they are compiled
//! once per combination of [`specializations`] (naga's SPIR-V writer has no specialization
//! constants, so the values are baked in here). The driver then sees constant loop bounds and
//! branches and drops the unused code: llvmpipe runs both sides of a branch on a uniform value.
//!
//! Besides the blobs, `$OUT_DIR/modules.rs` holds what Rust must agree on with the shaders, taken
//! from the shaders themselves so the two cannot drift apart:
//! - the table of specialized blobs, keyed by a typed `Overrides` value (`src/lib.rs`) whose
//!   field names are the WGSL override names (a renamed override fails to compile);
//! - the single pass's limits: its layers (`const MAX_LAYERS` in `lens.wgsl`, next to the
//!   varyings that set it; checked against the number of varyings `vs_single_pass` writes) and
//!   its viewpoint samples (`const MAX_VIEWPOINTS`, checked against the cube-map arrays the file
//!   binds); the varyings of its path-class form (`const SINGLE_PASS_SLOTS`, checked against the
//!   varyings `vs_single_pass_classes` writes);
//! - every push-constant (`var<immediate>`) struct as a `#[repr(C)]` Rust struct with naga's
//!   offsets, explicit padding, and compile-time assertions of its size and every field's offset;
//! - per file, a module `lensmap_shaders::<file>` of its contracts (`build/contracts.rs`): an enum
//!   of its entry points, its resources' binding numbers and kinds, its module-scope constants
//!   (one name in two files must have one value) and its structs' sizes.

use std::{collections::BTreeMap, env, fmt::Write as _, fs, path::Path};

#[path = "build/contracts.rs"]
mod contracts;

/// The WGSL `const` in `lens.wgsl` that bounds the single pass's layer count.
const MAX_LAYERS_CONSTANT: &str = "MAX_LAYERS";

/// The WGSL `const` in `lens.wgsl` that bounds the viewpoint samples the single pass blends.
const MAX_VIEWPOINTS_CONSTANT: &str = "MAX_VIEWPOINTS";

/// The WGSL `const` in `lens.wgsl`: the varyings of the single pass of path classes.
const SLOTS_CONSTANT: &str = "SINGLE_PASS_SLOTS";

/// The specialized entry point of the single pass of path classes, compiled per class count.
const CLASSES_ENTRY: &str = "fs_single_pass_classes_specialized";

/// What the single pass is compiled for: its file's `const MAX_LAYERS`, `const MAX_VIEWPOINTS`
/// and `const SINGLE_PASS_SLOTS`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SinglePassBounds {
    max_layers: u32,
    max_viewpoints: u32,
    slots: u32,
}

/// The folder, inside `wgsl/`, of the WGSL that files share: a line `// #include "NAME"` in a
/// shader is replaced by the text of `wgsl/include/NAME` before naga sees the file (WGSL has no
/// includes), so a piece several files need, such as the full-screen vertex stage, is written
/// once. The folder's files are not compiled on their own.
const INCLUDE_DIR: &str = "include";

/// The directive that pastes a shared file in place.
const INCLUDE_DIRECTIVE: &str = "// #include ";

/// `source` with every `// #include "NAME"` line replaced by the text of `include_dir/NAME`.
/// (Naga's diagnostics then count lines in the expanded text, and quote it.)
fn expand_includes(source: &str, include_dir: &Path, shown: &str) -> Result<String, String> {
    let mut expanded = String::with_capacity(source.len());
    for (number, line) in source.lines().enumerate() {
        let Some(name) = line.trim().strip_prefix(INCLUDE_DIRECTIVE) else {
            expanded.push_str(line);
            expanded.push('\n');
            continue;
        };
        let name = name.trim().trim_matches('"');
        let path = include_dir.join(name);
        println!("cargo:rerun-if-changed={}", path.display());
        let text = fs::read_to_string(&path).map_err(|error| {
            format!(
                "error: {shown}:{}: {INCLUDE_DIRECTIVE}\"{name}\": {}: {error}",
                number + 1,
                path.display()
            )
        })?;
        expanded.push_str(&text);
        if !text.ends_with('\n') {
            expanded.push('\n');
        }
    }
    Ok(expanded)
}

/// Override constants and the values specialized entry point `entry` is compiled for: every
/// layer count up to the shader's `MAX_LAYERS` and every viewpoint count up to its
/// `MAX_VIEWPOINTS`; for the greedy terms' single pass each non-empty term set (bit 0
/// refraction, bit 1 reflection) and no classes, for the single pass of path classes
/// ([`CLASSES_ENTRY`]) every class count K that fits its varyings with n layers,
/// K·(n + 1) ≤ `SINGLE_PASS_SLOTS`, and no term mask. Every combination sets every override,
/// so that each names one `Overrides` value.
fn specializations(entry: &str, bounds: SinglePassBounds) -> Vec<Combination> {
    let layers = ("LAYER_COUNT", (1..=bounds.max_layers).collect());
    let viewpoints = ("VIEWPOINTS", (1..=bounds.max_viewpoints).collect());
    if entry != CLASSES_ENTRY {
        return combinations(&[
            layers,
            ("TERM_MASK", vec![1, 2, 3]),
            viewpoints,
            ("CLASS_COUNT", vec![0]),
        ]);
    }
    combinations(&[
        layers,
        ("TERM_MASK", vec![0]),
        viewpoints,
        ("CLASS_COUNT", (1..=bounds.slots).collect()),
    ])
    .into_iter()
    .filter(|c| {
        let value = |name: &str| c.iter().find(|(n, _)| *n == name).map_or(0, |(_, v)| *v);
        value("CLASS_COUNT") * (value("LAYER_COUNT") + 1) <= bounds.slots
    })
    .collect()
}

/// Every combination of the specialization values, as (name, value) lists.
fn combinations(specializations: &[(&'static str, Vec<u32>)]) -> Vec<Combination> {
    let mut all = vec![Vec::new()];
    for (name, values) in specializations {
        all = all
            .into_iter()
            .flat_map(|prefix| {
                values.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push((*name, *v));
                    c
                })
            })
            .collect();
    }
    all
}

/// A readable form of one combination, for file names and messages: `LAYER_COUNT=3,TERM_MASK=3`.
fn key(combination: &[(&str, u32)]) -> String {
    combination
        .iter()
        .map(|(n, v)| format!("{n}={v}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// Override values of one specialization, as (name, value); empty for none.
type Combination = Vec<(&'static str, u32)>;

/// What one shader file compiled to.
struct Compiled {
    /// (entry point, override values, SPIR-V words).
    blobs: Vec<(String, Combination, Vec<u32>)>,
    /// Rust source of the file's push-constant structs, by struct name.
    push_constants: Vec<(String, String)>,
    /// The file's single-pass limits, if it declares them.
    single_pass: Option<SinglePassBounds>,
    /// What Rust must agree on with it ([`contracts::contracts`]).
    contracts: contracts::Contracts,
}

fn main() {
    let out_dir = env::var("OUT_DIR").expect("cargo sets OUT_DIR for build scripts");
    let manifest = env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let source_dir = Path::new(&manifest).join("wgsl");
    println!("cargo:rerun-if-changed={}", source_dir.display());

    let mut entries: Vec<_> = fs::read_dir(&source_dir)
        .expect("shaders/wgsl exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "wgsl"))
        .collect();
    entries.sort();

    let mut modules = String::from("pub(crate) const MODULES: &[(&str, &str, &[u8])] = &[\n");
    let mut specialized =
        String::from("pub(crate) const SPECIALIZED: &[(&str, &str, Overrides, &[u8])] = &[\n");
    let mut push_constants = String::new();
    let mut emitted: BTreeMap<String, String> = BTreeMap::new();
    let mut single_pass = None;
    let mut contract_modules = String::new();
    // Every module-scope constant with the file that first declared it: a name two files declare
    // must have one value (the control words of the tessellation's passes, say).
    let mut constants: BTreeMap<String, (String, contracts::Constant)> = BTreeMap::new();
    let mut failed = false;
    for path in &entries {
        println!("cargo:rerun-if-changed={}", path.display());
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let shown = format!("shaders/wgsl/{stem}.wgsl");
        let source = fs::read_to_string(path).expect("shader source is readable");
        let compiled = expand_includes(&source, &source_dir.join(INCLUDE_DIR), &shown)
            .and_then(|source| compile(&source, &stem, &shown));
        match compiled {
            Ok(compiled) => {
                for (entry, overrides, words) in compiled.blobs {
                    let file = if overrides.is_empty() {
                        format!("{stem}.{entry}.spv")
                    } else {
                        format!(
                            "{stem}.{entry}.{}.spv",
                            key(&overrides).replace([',', '='], "_")
                        )
                    };
                    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                    fs::write(Path::new(&out_dir).join(&file), bytes).expect("OUT_DIR is writable");
                    let blob = format!("include_bytes!(concat!(env!(\"OUT_DIR\"), \"/{file}\"))");
                    if overrides.is_empty() {
                        let _ = writeln!(modules, "    (\"{stem}\", \"{entry}\", {blob}),");
                    } else {
                        // Field names are the override names: a renamed override fails to compile.
                        let fields: Vec<String> = overrides
                            .iter()
                            .map(|(name, value)| format!("{}: {value}", name.to_lowercase()))
                            .collect();
                        let _ = writeln!(
                            specialized,
                            "    (\"{stem}\", \"{entry}\", Overrides {{ {} }}, {blob}),",
                            fields.join(", ")
                        );
                    }
                }
                // Files that share an include share its push-constant struct: written once.
                for (name, text) in compiled.push_constants {
                    match emitted.get(&name) {
                        None => {
                            push_constants.push_str(&text);
                            emitted.insert(name, text);
                        }
                        Some(first) if *first == text => {}
                        Some(_) => {
                            eprintln!(
                                "error: {shown}: push constants `{name}` differ from another file's struct of that name: rename one"
                            );
                            failed = true;
                        }
                    }
                }
                contract_modules.push_str(&compiled.contracts.module);
                for (name, constant) in compiled.contracts.constants {
                    match constants.get(&name) {
                        None => {
                            constants.insert(name, (shown.clone(), constant));
                        }
                        Some((_, first)) if *first == constant => {}
                        Some((other, first)) => {
                            eprintln!(
                                "error: {shown}: `const {name}` is {} but {other} declares it {}: one name, one value (share it through an include)",
                                constant.value, first.value
                            );
                            failed = true;
                        }
                    }
                }
                if let Some(found) = compiled.single_pass {
                    if single_pass.is_some() {
                        eprintln!(
                            "error: {shown}: a second `const {MAX_LAYERS_CONSTANT}`; declare it once, in lens.wgsl"
                        );
                        failed = true;
                    }
                    single_pass = Some(found);
                }
            }
            Err(message) => {
                // cargo shows build-script stderr on failure; `error:` lines stand out.
                for line in message.lines() {
                    println!("cargo:warning={line}");
                }
                eprintln!("{message}");
                failed = true;
            }
        }
    }
    if failed {
        std::process::exit(1);
    }
    let Some(SinglePassBounds {
        max_layers,
        max_viewpoints,
        slots,
    }) = single_pass
    else {
        eprintln!("error: shaders/wgsl/lens.wgsl: `const {MAX_LAYERS_CONSTANT}: u32` is missing");
        std::process::exit(1);
    };
    modules.push_str("];\n");
    specialized.push_str("];\n");
    let mut generated =
        String::from("// Generated by shaders/build.rs from shaders/wgsl/*.wgsl.\n\n");
    let _ = writeln!(
        generated,
        "/// Most layers the single-pass fragment shader composites (`const {MAX_LAYERS_CONSTANT}` in \
         `lens.wgsl`, which has one interpolated direction per layer and term).\n\
         pub const {MAX_LAYERS_CONSTANT}: u32 = {max_layers};\n\n\
         /// Most viewpoint samples the single-pass fragment shader blends (`const \
         {MAX_VIEWPOINTS_CONSTANT}` in `lens.wgsl`, which binds one cube-map array per sample).\n\
         pub const {MAX_VIEWPOINTS_CONSTANT}: u32 = {max_viewpoints};\n\n\
         /// Varyings of the single pass of path classes (`const {SLOTS_CONSTANT}` in `lens.wgsl`): \
         K classes of n layers take K·(n + 1).\n\
         pub const {SLOTS_CONSTANT}: u32 = {slots};\n"
    );
    generated.push_str(&modules);
    generated.push('\n');
    generated.push_str(&specialized);
    generated.push_str(&push_constants);
    generated.push_str(&contract_modules);
    fs::write(Path::new(&out_dir).join("modules.rs"), generated).expect("OUT_DIR is writable");
}

/// Parses and validates one file; writes one SPIR-V module per entry point (and per
/// specialization); reads its single-pass limits and push-constant structs.
fn compile(source: &str, stem: &str, shown: &str) -> Result<Compiled, String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| e.emit_to_string_with_path(source, shown))?;
    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::IMMEDIATES
            | naga::valid::Capabilities::FLOAT64
            | naga::valid::Capabilities::CUBE_ARRAY_TEXTURES
            | naga::valid::Capabilities::RAY_QUERY,
    );
    let info = validator
        .validate(&module)
        .map_err(|e| e.emit_to_string_with_path(source, shown))?;
    let single_pass =
        single_pass_bounds(&module).map_err(|problem| format!("error: {shown}: {problem}"))?;
    // Vulkan conventions throughout (y down in clip space, depth 0..1): no coordinate flip.
    let options = naga::back::spv::Options {
        lang_version: (1, 3),
        flags: naga::back::spv::WriterFlags::LABEL_VARYINGS,
        // Bindings come straight from the WGSL @group/@binding attributes.
        fake_missing_bindings: true,
        ..Default::default()
    };
    let mut blobs = Vec::new();
    for ep in &module.entry_points {
        let pipeline = naga::back::spv::PipelineOptions {
            shader_stage: ep.stage,
            entry_point: ep.name.clone(),
        };
        let specializations = if ep.name.ends_with("_specialized") {
            let Some(bounds) = single_pass else {
                return Err(format!(
                    "error: {shown}: entry point `{}` is specialized per layer count, but the file \
                     declares no `const {MAX_LAYERS_CONSTANT}: u32`",
                    ep.name
                ));
            };
            specializations(&ep.name, bounds)
        } else {
            vec![Vec::new()]
        };
        for combination in specializations {
            let mut constants = naga::back::PipelineConstants::default();
            for (name, value) in &combination {
                constants.insert((*name).to_string(), f64::from(*value));
            }
            let (resolved, resolved_info) = naga::back::pipeline_constants::process_overrides(
                &module,
                &info,
                Some((ep.stage, &ep.name)),
                &constants,
            )
            .map_err(|e| {
                format!(
                    "error: {shown}: entry point `{}`: overrides {}: {e}",
                    ep.name,
                    key(&combination)
                )
            })?;
            let words =
                naga::back::spv::write_vec(&resolved, &resolved_info, &options, Some(&pipeline))
                    .map_err(|e| format!("error: {shown}: entry point `{}`: {e}", ep.name))?;
            blobs.push((ep.name.clone(), combination, words));
        }
    }
    let blob = |entry: &str| format!("{stem}.{entry}.spv");
    Ok(Compiled {
        blobs,
        push_constants: push_constant_structs(&module, shown)?,
        single_pass,
        contracts: contracts::contracts(&module, &info, stem, shown, &blob)?,
    })
}

/// The module's single-pass limits, checked against what its single pass declares: none if it
/// declares no `const MAX_LAYERS`; with it, `const MAX_VIEWPOINTS` is required.
fn single_pass_bounds(module: &naga::Module) -> Result<Option<SinglePassBounds>, String> {
    let Some(max_layers) = u32_constant(module, MAX_LAYERS_CONSTANT)? else {
        return Ok(None);
    };
    let max_viewpoints = u32_constant(module, MAX_VIEWPOINTS_CONSTANT)?.ok_or_else(|| {
        format!(
            "`const {MAX_LAYERS_CONSTANT}` needs `const {MAX_VIEWPOINTS_CONSTANT}: u32` beside it"
        )
    })?;
    let slots = u32_constant(module, SLOTS_CONSTANT)?.ok_or_else(|| {
        format!("`const {MAX_LAYERS_CONSTANT}` needs `const {SLOTS_CONSTANT}: u32` beside it")
    })?;
    let found = varyings(module, "vs_single_pass")?;
    if found != 2 * max_layers as usize + 2 {
        return Err(format!(
            "`vs_single_pass` writes {found} varyings but `const {MAX_LAYERS_CONSTANT} = {max_layers}` \
             needs {} (a direction per layer and term, and two F·G): change both together",
            2 * max_layers + 2
        ));
    }
    let found = varyings(module, "vs_single_pass_classes")?;
    if found != slots as usize {
        return Err(format!(
            "`vs_single_pass_classes` writes {found} varyings but `const {SLOTS_CONSTANT} = {slots}` \
             needs as many: change both together"
        ));
    }
    check_single_pass_layers(module, max_viewpoints)?;
    Ok(Some(SinglePassBounds {
        max_layers,
        max_viewpoints,
        slots,
    }))
}

/// The single pass samples one cube-map array per viewpoint sample: the module must bind exactly
/// `MAX_VIEWPOINTS` of them, or raising the constant without a binding (and the fragment code
/// that samples it) would compile a shader that silently blends fewer viewpoints.
fn check_single_pass_layers(module: &naga::Module, max_viewpoints: u32) -> Result<(), String> {
    let arrays = module
        .global_variables
        .iter()
        .filter(|(_, global)| {
            matches!(
                module.types[global.ty].inner,
                naga::TypeInner::Image {
                    dim: naga::ImageDimension::Cube,
                    arrayed: true,
                    ..
                }
            )
        })
        .count();
    if arrays == max_viewpoints as usize {
        Ok(())
    } else {
        Err(format!(
            "the file binds {arrays} cube-map arrays but `const {MAX_VIEWPOINTS_CONSTANT} = \
             {max_viewpoints}` needs one per viewpoint sample: change both together"
        ))
    }
}

/// The location varyings vertex entry point `entry` writes. A single pass's vertex stage must
/// write exactly those its constant sets (`2·MAX_LAYERS + 2` for the greedy terms': a direction
/// per layer and term, two F·G; `SINGLE_PASS_SLOTS` for the path classes'), or raising the
/// constant without adding varyings (and the fragment code that reads them) would compile a
/// shader that silently composites fewer layers.
fn varyings(module: &naga::Module, entry: &str) -> Result<usize, String> {
    let found = module
        .entry_points
        .iter()
        .find(|ep| ep.name == entry)
        .ok_or_else(|| format!("`const {MAX_LAYERS_CONSTANT}` needs the entry point `{entry}`"))?;
    let locations =
        found
            .function
            .result
            .as_ref()
            .map_or(0, |result| match &module.types[result.ty].inner {
                naga::TypeInner::Struct { members, .. } => members
                    .iter()
                    .filter(|m| matches!(m.binding, Some(naga::Binding::Location { .. })))
                    .count(),
                _ => 0,
            });
    Ok(locations)
}

/// The value of the module's `const NAME: u32 = …;`, if it declares one.
fn u32_constant(module: &naga::Module, name: &str) -> Result<Option<u32>, String> {
    let Some((_, constant)) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
    else {
        return Ok(None);
    };
    match module.global_expressions[constant.init] {
        naga::Expression::Literal(naga::Literal::U32(value)) if value > 0 => Ok(Some(value)),
        _ => Err(format!(
            "`const {name}` must be a positive u32 literal such as `6u`"
        )),
    }
}

/// Rust for every push-constant (`var<immediate>`) struct of the module: `#[repr(C)]`, the
/// members at naga's offsets with explicit zero padding between and after them, and compile-time
/// assertions of the size and of every member's offset.
fn push_constant_structs(
    module: &naga::Module,
    shown: &str,
) -> Result<Vec<(String, String)>, String> {
    let mut structs = Vec::new();
    let mut seen = BTreeMap::new();
    for (_, global) in module.global_variables.iter() {
        if global.space != naga::AddressSpace::Immediate {
            continue;
        }
        let ty = &module.types[global.ty];
        let (Some(name), naga::TypeInner::Struct { members, span }) = (&ty.name, &ty.inner) else {
            return Err(format!(
                "error: {shown}: push constants must be one named struct (var<immediate>)"
            ));
        };
        if seen.insert(name.clone(), ()).is_some() {
            continue;
        }
        let mut out = String::new();
        let _ = writeln!(
            out,
            "\n/// The push constants `{name}` of the shaders (`var<immediate>`), laid out as naga \
             lays them out ({span} bytes): generated from the shader, so the two cannot disagree.\n\
             #[repr(C)]\n\
             #[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]\n\
             pub struct {name} {{"
        );
        let mut at = 0u32;
        let mut asserts = Vec::new();
        for member in members {
            let field = member
                .name
                .clone()
                .ok_or_else(|| format!("error: {shown}: {name} has an unnamed member"))?;
            if member.offset > at {
                let _ = writeln!(
                    out,
                    "    /// Padding naga leaves before `{field}`; zero.\n    pub _pad_{at}: [u8; {}],",
                    member.offset - at
                );
            }
            let (rust, size, wgsl) = rust_type(&module.types[member.ty].inner).ok_or_else(|| {
                format!("error: {shown}: {name}.{field}: push-constant member type not supported by build.rs")
            })?;
            let _ = writeln!(
                out,
                "    /// WGSL `{field}: {wgsl}` at byte offset {}.\n    pub {field}: {rust},",
                member.offset
            );
            asserts.push(format!(
                "const _: () = assert!(core::mem::offset_of!({name}, {field}) == {});",
                member.offset
            ));
            at = member.offset + size;
        }
        if *span > at {
            let _ = writeln!(
                out,
                "    /// Padding up to the struct's size; zero.\n    pub _pad_{at}: [u8; {}],",
                span - at
            );
        }
        out.push_str("}\n");
        let _ = writeln!(
            out,
            "const _: () = assert!(core::mem::size_of::<{name}>() == {span});"
        );
        for line in asserts {
            out.push_str(&line);
            out.push('\n');
        }
        structs.push((name.clone(), out));
    }
    Ok(structs)
}

/// The Rust type, byte size and WGSL spelling of a push-constant member (32-bit scalars, vectors
/// and 4-row matrices: the types whose Rust and WGSL layouts agree without inner padding).
fn rust_type(inner: &naga::TypeInner) -> Option<(String, u32, String)> {
    let scalar = |s: &naga::Scalar| match (s.kind, s.width) {
        (naga::ScalarKind::Float, 4) => Some(("f32", "f32")),
        (naga::ScalarKind::Uint, 4) => Some(("u32", "u32")),
        (naga::ScalarKind::Sint, 4) => Some(("i32", "i32")),
        _ => None,
    };
    match inner {
        naga::TypeInner::Scalar(s) => {
            let (rust, wgsl) = scalar(s)?;
            Some((rust.to_owned(), 4, wgsl.to_owned()))
        }
        naga::TypeInner::Vector { size, scalar: s } => {
            let (rust, wgsl) = scalar(s)?;
            let n = *size as u32;
            Some((format!("[{rust}; {n}]"), 4 * n, format!("vec{n}<{wgsl}>")))
        }
        naga::TypeInner::Matrix {
            columns,
            rows: naga::VectorSize::Quad,
            scalar: s,
        } => {
            let (rust, wgsl) = scalar(s)?;
            let c = *columns as u32;
            Some((
                format!("[[{rust}; 4]; {c}]"),
                16 * c,
                format!("mat{c}x4<{wgsl}>"),
            ))
        }
        _ => None,
    }
}
