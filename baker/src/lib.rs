//! The offline baker: infers lensmap's layered environment maps so that the hardware rendering
//! matches the reference ray tracer (hybrid-rendering paper §4.2–4.3). The rooms: [`clustering`]
//! places layer shells (LBG); [`matrix`] measures rendering matrices from test renderings read
//! back from the device; [`targets`] turns intersection records into per-layer targets and
//! confidence; [`solve`] finds the EM over all MIP levels by confidence-weighted, regularized
//! least squares; [`direct`] adds direct images from the EM origin for texels no lens view
//! constrains; [`infer`] runs them for one lens object at one camera. Over a whole view space,
//! [`placement`] clusters the records of many viewpoints into layers and fits each a shell, and
//! [`bake`] plans, bakes sample by sample, resumes and merges shards.

pub mod bake;
pub mod bounce;
pub mod clustering;
pub mod direct;
pub mod infer;
pub mod matrix;
pub mod placement;
pub mod solve;
pub mod targets;
