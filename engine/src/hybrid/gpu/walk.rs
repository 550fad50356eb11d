//! How the tracer's passes find a ray's hits: set 0's bindings 0 and 3, and the shader that
//! reads them. Both walks test the same triangles with the same test and tie rule
//! (`shaders/wgsl/include/vertex_paths.wgsl`); they differ in what culls the triangles a ray
//! cannot hit.

use lensmap_shaders::{EntryPoint, Shader, tracer, tracer_f64, tracer_rq, tracer_rq_f64};

use super::buffers::{check_range, storage};
use crate::gpu::descriptors::Resource;
use crate::gpu::{Buffer, Gpu, GpuError, acceleration::BoxScene};
use crate::hybrid::paths::VertexPrecision;
use crate::trace::bvh_gpu::{GpuGeometry, STACK_ENTRIES};

/// The walk the GPU tracer uses, once chosen for a device
/// ([`crate::hybrid::Traversal::resolve`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuTraversal {
    /// A binary BVH per part built by obvhs on the CPU, walked with a stack in the compute
    /// shader (`tracer.wgsl`): every Vulkan 1.3 device.
    Bvh,
    /// The driver's acceleration structures over each triangle's box, walked with ray queries
    /// (`tracer_rq.wgsl`): devices with [`Gpu::ray_queries`].
    Driver,
}

impl GpuTraversal {
    /// The name `--traversal` takes.
    pub fn name(self) -> &'static str {
        match self {
            GpuTraversal::Bvh => "bvh",
            GpuTraversal::Driver => "driver",
        }
    }
}

/// How the GPU tracer finds a ray's hits (`--traversal`), before a device is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Traversal {
    /// The walk measured faster on the device (`docs/results.md#gpu-traversal`).
    #[default]
    Auto,
    /// [`GpuTraversal::Bvh`].
    Bvh,
    /// [`GpuTraversal::Driver`]; an error on a device without ray queries.
    Driver,
}

impl Traversal {
    /// The name `--traversal` takes.
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Auto => "auto",
            Traversal::Bvh => "bvh",
            Traversal::Driver => "driver",
        }
    }

    /// The walk this choice takes on `gpu`, or why it cannot.
    pub fn resolve(self, gpu: &Gpu) -> Result<GpuTraversal, GpuError> {
        match self {
            Traversal::Auto => Ok(GpuTraversal::Bvh),
            Traversal::Bvh => Ok(GpuTraversal::Bvh),
            Traversal::Driver if gpu.ray_queries() => Ok(GpuTraversal::Driver),
            Traversal::Driver => Err(GpuError::NoSuitableDevice(format!(
                "{} ({}) has no acceleration structures with ray queries: lensmap makes its device with them where the driver offers VK_KHR_acceleration_structure and VK_KHR_ray_query, and uses a host's device without them; walk the tracer's own BVH instead",
                gpu.device_name(),
                gpu.device_id().driver_description()
            ))),
        }
    }
}

/// What a walk reads, resident on the device.
pub(super) enum Walk {
    /// The BVHs' nodes (binding 0) and each part's root node (binding 3).
    Bvh {
        nodes: crate::gpu::Buffer,
        roots: crate::gpu::Buffer,
    },
    /// The acceleration structures (binding 0) and each part's triangle range (binding 3).
    Driver {
        scene: BoxScene,
        ranges: crate::gpu::Buffer,
    },
}

impl Walk {
    /// Makes `geometry`'s walk resident on `gpu`; refuses geometry it cannot walk whole.
    pub(super) fn new(
        gpu: &Gpu,
        geometry: &GpuGeometry,
        traversal: GpuTraversal,
    ) -> Result<Walk, GpuError> {
        match traversal {
            GpuTraversal::Bvh => {
                if geometry.depth >= STACK_ENTRIES {
                    return Err(GpuError::BadUpload {
                        what: "tracer BVH".into(),
                        problem: format!(
                            "a part's BVH is {} levels deep, past the {STACK_ENTRIES} entries of the GPU tracer's traversal stack; trace this scene on the CPU",
                            geometry.depth
                        ),
                    });
                }
                check_range(gpu, "tracer nodes", geometry.nodes.len())?;
                Ok(Walk::Bvh {
                    nodes: storage(gpu, "tracer nodes", &geometry.nodes)?,
                    roots: storage(gpu, "tracer roots", &geometry.roots)?,
                })
            }
            GpuTraversal::Driver => Ok(Walk::Driver {
                scene: BoxScene::build(gpu, &geometry.boxes)?,
                ranges: storage(gpu, "tracer part ranges", &geometry.ranges)?,
            }),
        }
    }

    /// Which walk this is.
    pub(super) fn traversal(&self) -> GpuTraversal {
        match self {
            Walk::Bvh { .. } => GpuTraversal::Bvh,
            Walk::Driver { .. } => GpuTraversal::Driver,
        }
    }

    /// Set 0 of its passes, as the shader declares it.
    pub(super) fn set(&self) -> &'static [lensmap_shaders::Binding] {
        match self {
            Walk::Bvh { .. } => tracer::SETS[0],
            Walk::Driver { .. } => tracer_rq::SETS[0],
        }
    }

    /// Its passes' shaders in `precision`: the pass over given vertices, then the pass over a
    /// tessellation level's new vertices.
    pub(super) fn shaders(&self, precision: VertexPrecision) -> [Shader; 2] {
        match (self.traversal(), precision) {
            (GpuTraversal::Bvh, VertexPrecision::F32) => [
                tracer::Entry::CsVertexPaths.shader(),
                tracer::Entry::CsLevelPaths.shader(),
            ],
            (GpuTraversal::Bvh, VertexPrecision::F64) => [
                tracer_f64::Entry::CsVertexPaths.shader(),
                tracer_f64::Entry::CsLevelPaths.shader(),
            ],
            (GpuTraversal::Driver, VertexPrecision::F32) => [
                tracer_rq::Entry::CsVertexPaths.shader(),
                tracer_rq::Entry::CsLevelPaths.shader(),
            ],
            (GpuTraversal::Driver, VertexPrecision::F64) => [
                tracer_rq_f64::Entry::CsVertexPaths.shader(),
                tracer_rq_f64::Entry::CsLevelPaths.shader(),
            ],
        }
    }

    /// The buffers at bindings 0 and 3 with the names a plan gives them (the driver's binding 0
    /// is its acceleration structure: no buffer).
    pub(super) fn buffers(&self) -> [(Option<&Buffer>, &'static str); 2] {
        match self {
            Walk::Bvh { nodes, roots } => {
                [(Some(nodes), "tracer nodes"), (Some(roots), "tracer roots")]
            }
            Walk::Driver { ranges, .. } => [(None, ""), (Some(ranges), "tracer part ranges")],
        }
    }

    /// What bindings 0 and 3 of set 0 point at.
    pub(super) fn resources(&self) -> (Resource, Resource) {
        match self {
            Walk::Bvh { nodes, roots } => (
                Resource::Buffer(nodes.handle),
                Resource::Buffer(roots.handle),
            ),
            Walk::Driver { scene, ranges } => (
                Resource::AccelerationStructure(scene.top.handle),
                Resource::Buffer(ranges.handle),
            ),
        }
    }
}
