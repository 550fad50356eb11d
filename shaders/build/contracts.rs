//! What Rust must agree on with one shader file, read from naga's module of it: its entry points
//! as an enum (with their blobs and workgroup sizes), its resources' binding numbers and kinds,
//! its module-scope constants and its structs' sizes. `build.rs` writes each file's as a Rust
//! module `lensmap_shaders::<file>`, so that Rust names a binding, a control word or an entry
//! point only through them: a renamed or renumbered one in WGSL fails the build, and one that
//! does not exist cannot be named.

use std::{collections::BTreeMap, fmt::Write as _};

/// A constant as Rust writes it: its type and value.
#[derive(Clone, Debug, PartialEq)]
pub struct Constant {
    /// `u32`, `i32` or `f32`.
    pub ty: &'static str,
    /// The literal, as Rust writes it.
    pub value: String,
}

/// One file's contracts.
pub struct Contracts {
    /// The Rust module's text.
    pub module: String,
    /// Its module-scope constants (what other files must agree with).
    pub constants: BTreeMap<String, Constant>,
}

/// `cs_scan_blocks` → `CsScanBlocks`.
fn camel(snake: &str) -> String {
    snake
        .split('_')
        .filter(|part| !part.is_empty())
        .map(|part| {
            let mut chars = part.chars();
            chars.next().map_or_else(String::new, |first| {
                first.to_uppercase().chain(chars).collect::<String>()
            })
        })
        .collect()
}

/// `VertexRecord` → `VERTEX_RECORD`; `lens_data` → `LENS_DATA`.
fn screaming(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_uppercase() && i > 0 && !out.ends_with('_') {
            out.push('_');
        }
        out.extend(c.to_uppercase());
    }
    out
}

/// The binding kind of a resource, as `lensmap_shaders::BindingKind` names it.
fn binding_kind(
    module: &naga::Module,
    global: &naga::GlobalVariable,
) -> Result<&'static str, String> {
    let inner = match &module.types[global.ty].inner {
        naga::TypeInner::BindingArray { base, .. } => &module.types[*base].inner,
        inner => inner,
    };
    Ok(match (global.space, inner) {
        (naga::AddressSpace::Storage { access }, _) => {
            if access.contains(naga::StorageAccess::STORE) {
                "StorageReadWrite"
            } else {
                "StorageRead"
            }
        }
        (naga::AddressSpace::Uniform, _) => "Uniform",
        (_, naga::TypeInner::Image { .. }) => "SampledImage",
        (_, naga::TypeInner::Sampler { .. }) => "Sampler",
        (_, naga::TypeInner::AccelerationStructure { .. }) => "AccelerationStructure",
        (space, _) => {
            return Err(format!(
                "a resource in {space:?} that build.rs does not know"
            ));
        }
    })
}

/// The bit of `stage` in `lensmap_shaders::Binding::stages`.
fn stage_bit(stage: naga::ShaderStage) -> u32 {
    match stage {
        naga::ShaderStage::Vertex => 1,
        naga::ShaderStage::Fragment => 2,
        naga::ShaderStage::Compute => 4,
        _ => 0,
    }
}

/// The resources an entry point reads or writes (`crate::Use` literals), in binding order.
fn resource_uses(module: &naga::Module, function: &naga::valid::FunctionInfo) -> Vec<String> {
    let mut uses: Vec<(u32, u32, &str)> = module
        .global_variables
        .iter()
        .filter_map(|(handle, global)| {
            let binding = global.binding.as_ref()?;
            let flags = function[handle];
            let read =
                flags.intersects(naga::valid::GlobalUse::READ | naga::valid::GlobalUse::ATOMIC);
            let write =
                flags.intersects(naga::valid::GlobalUse::WRITE | naga::valid::GlobalUse::ATOMIC);
            let access = match (read, write) {
                (_, true) if read => "ReadWrite",
                (_, true) => "Write",
                (true, false) => "Read",
                (false, false) => return None,
            };
            Some((binding.group, binding.binding, access))
        })
        .collect();
    uses.sort();
    uses.iter()
        .map(|(group, binding, access)| {
            format!("crate::Use {{ group: {group}, binding: {binding}, access: crate::Access::{access} }}")
        })
        .collect()
}

/// The contracts of `stem`'s module; `blob` names an entry point's SPIR-V file.
pub fn contracts(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    stem: &str,
    shown: &str,
    blob: &dyn Fn(&str) -> String,
) -> Result<Contracts, String> {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n/// The contracts of `{shown}`, generated from it by `build.rs`.\npub mod {stem} {{"
    );
    // Entry points: the plain ones as `Entry`, the specialized ones as `Specialized`.
    let (specialized, plain): (Vec<_>, Vec<_>) = module
        .entry_points
        .iter()
        .partition(|ep| ep.name.ends_with("_specialized"));
    if !plain.is_empty() {
        let _ = writeln!(
            out,
            "    /// Its entry points (an entry's discriminant is its index in [`Entry::ALL`]).\n    \
             #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]\n    pub enum Entry {{"
        );
        for ep in &plain {
            let [x, y, z] = ep.workgroup_size;
            let _ = writeln!(
                out,
                "        /// `{}` ({:?}{}).\n        {},",
                ep.name,
                ep.stage,
                if ep.stage == naga::ShaderStage::Compute {
                    format!(", workgroup {x}×{y}×{z}")
                } else {
                    String::new()
                },
                camel(&ep.name)
            );
        }
        out.push_str("    }\n\n    impl crate::EntryPoint for Entry {\n");
        let all: Vec<String> = plain
            .iter()
            .map(|ep| format!("Entry::{}", camel(&ep.name)))
            .collect();
        let _ = writeln!(
            out,
            "        const ALL: &'static [Entry] = &[{}];",
            all.join(", ")
        );
        out.push_str("        fn name(self) -> &'static str {\n            match self {\n");
        for ep in &plain {
            let _ = writeln!(
                out,
                "                Entry::{} => \"{}\",",
                camel(&ep.name),
                ep.name
            );
        }
        out.push_str("            }\n        }\n        fn shader(self) -> crate::Shader {\n            let spirv: &'static [u8] = match self {\n");
        for ep in &plain {
            let _ = writeln!(
                out,
                "                Entry::{} => include_bytes!(concat!(env!(\"OUT_DIR\"), \"/{}\")),",
                camel(&ep.name),
                blob(&ep.name)
            );
        }
        let _ = writeln!(
            out,
            "            }};\n            crate::Shader {{ file: \"{stem}\", entry: self.name(), overrides: None, spirv }}\n        }}"
        );
        out.push_str("        fn workgroup_size(self) -> [u32; 3] {\n            match self {\n");
        for ep in &plain {
            let [x, y, z] = ep.workgroup_size;
            let _ = writeln!(
                out,
                "                Entry::{} => [{x}, {y}, {z}],",
                camel(&ep.name)
            );
        }
        out.push_str("            }\n        }\n        fn uses(self) -> &'static [crate::Use] {\n            match self {\n");
        for ep in &plain {
            let index = module
                .entry_points
                .iter()
                .position(|e| e.name == ep.name)
                .unwrap_or(0);
            let uses = resource_uses(module, info.get_entry_point(index));
            let _ = writeln!(
                out,
                "                Entry::{} => &[{}],",
                camel(&ep.name),
                uses.join(", ")
            );
        }
        out.push_str("            }\n        }\n        fn index(self) -> usize {\n            self as usize\n        }\n    }\n");
    }
    if !specialized.is_empty() {
        let _ = writeln!(
            out,
            "\n    /// Its entry points compiled once per combination of override values.\n    \
             #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]\n    pub enum Specialized {{"
        );
        for ep in &specialized {
            let _ = writeln!(
                out,
                "        /// `{}`.\n        {},",
                ep.name,
                camel(&ep.name)
            );
        }
        out.push_str("    }\n\n    impl Specialized {\n        /// The entry point compiled with `overrides`, or `None` where `build.rs` did not\n        /// compile that combination.\n        pub fn shader(self, overrides: crate::Overrides) -> Option<crate::Shader> {\n            let name = match self {\n");
        for ep in &specialized {
            let _ = writeln!(
                out,
                "                Specialized::{} => \"{}\",",
                camel(&ep.name),
                ep.name
            );
        }
        let _ = writeln!(
            out,
            "            }};\n            crate::specialized(\"{stem}\", name, overrides)\n        }}\n    }}"
        );
    }
    // Resources: binding numbers by name, and each group's set in binding order.
    let mut groups: BTreeMap<u32, Vec<(u32, String, &'static str, u32)>> = BTreeMap::new();
    for (handle, global) in module.global_variables.iter() {
        let Some(binding) = &global.binding else {
            continue;
        };
        let name = global
            .name
            .clone()
            .ok_or_else(|| format!("error: {shown}: a resource without a name"))?;
        let kind =
            binding_kind(module, global).map_err(|e| format!("error: {shown}: {name}: {e}"))?;
        // The stages of the entry points that use it.
        let stages = module
            .entry_points
            .iter()
            .enumerate()
            .filter(|(i, _)| !info.get_entry_point(*i)[handle].is_empty())
            .fold(0u32, |bits, (_, ep)| bits | stage_bit(ep.stage));
        groups
            .entry(binding.group)
            .or_default()
            .push((binding.binding, name, kind, stages));
    }
    if !groups.is_empty() {
        out.push_str(
            "\n    /// Its resources' binding numbers, by variable name.\n    pub mod binding {\n",
        );
        for (group, bindings) in &groups {
            for (number, name, _, _) in bindings {
                let _ = writeln!(
                    out,
                    "        /// `{name}` (group {group}).\n        pub const {}: u32 = {number};",
                    screaming(name)
                );
            }
        }
        out.push_str("    }\n");
        let _ = writeln!(
            out,
            "\n    /// Its resources, per group (index = group number), in binding order.\n    pub const SETS: &[&[crate::Binding]] = &["
        );
        let last = groups.keys().max().copied().unwrap_or(0);
        for group in 0..=last {
            let mut bindings = groups.get(&group).cloned().unwrap_or_default();
            bindings.sort();
            for (i, (number, name, _, _)) in bindings.iter().enumerate() {
                if *number != i as u32 {
                    return Err(format!(
                        "error: {shown}: group {group}: `{name}` is binding {number} but the bindings before it are {i}: number a set's bindings 0, 1, 2, … without gaps"
                    ));
                }
            }
            let entries: Vec<String> = bindings
                .iter()
                .map(|(number, name, kind, stages)| {
                    format!(
                        "crate::Binding {{ binding: {number}, name: \"{name}\", kind: crate::BindingKind::{kind}, stages: {stages} }}"
                    )
                })
                .collect();
            let _ = writeln!(out, "        &[{}],", entries.join(", "));
        }
        out.push_str("    ];\n");
    }
    // Module-scope constants of a scalar type, with their WGSL names.
    let mut constants = BTreeMap::new();
    for (_, constant) in module.constants.iter() {
        let Some(name) = &constant.name else { continue };
        let (ty, value) = match module.global_expressions[constant.init] {
            naga::Expression::Literal(naga::Literal::U32(v)) => ("u32", format!("{v}")),
            naga::Expression::Literal(naga::Literal::I32(v)) => ("i32", format!("{v}")),
            naga::Expression::Literal(naga::Literal::F32(v)) => ("f32", format!("{v:?}")),
            _ => continue,
        };
        constants.insert(name.clone(), Constant { ty, value });
    }
    if !constants.is_empty() {
        out.push_str("\n    // Its module-scope constants.\n");
        for (name, constant) in &constants {
            let _ = writeln!(
                out,
                "    /// WGSL `const {name}`.\n    pub const {name}: {} = {};",
                constant.ty, constant.value
            );
        }
    }
    // Named structs' sizes, as naga lays them out.
    let mut sizes = BTreeMap::new();
    for (_, ty) in module.types.iter() {
        if let (Some(name), naga::TypeInner::Struct { span, .. }) = (&ty.name, &ty.inner) {
            sizes.insert(format!("{}_BYTES", screaming(name)), (name.clone(), *span));
        }
    }
    for (constant, (name, span)) in &sizes {
        let _ = writeln!(
            out,
            "    /// Bytes of WGSL `struct {name}`, as naga lays it out.\n    pub const {constant}: u32 = {span};"
        );
    }
    out.push_str("}\n");
    Ok(Contracts {
        module: out,
        constants,
    })
}
