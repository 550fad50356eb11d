//! Inference of one lens object's layered EM at one camera (a viewpoint sample): the EM
//! resolution from test renderings, then per layer the rendering matrices of both terms
//! ([`crate::matrix`]), the targets and confidence from intersection records
//! ([`crate::targets`]) and the solve over all MIP levels ([`crate::solve`]).

use std::{sync::Arc, time::Instant};

use lensmap::{
    cubemap::{CubeMap, sampling::sample_cube_trilinear},
    hybrid::{HybridOptions, HybridScene, ShadingTerms},
    index::{LayerIndex, LayerRef, LensIndex},
    layers::Layering,
    render::{Compositing, FrameInput, TargetFormat, UploadedFrame},
    runner::FrameRunner,
    scene::Camera,
    trace::{LensRecords, PathModel},
};

use crate::{
    matrix::{
        DigitEncoding, Digits, LayerFrame, LayerFrames, MatrixError, MeasureOptions,
        RenderingMatrix, TestRenderer, TexelLayout,
    },
    solve::{Equations, Smoothness, SolveError, SolveOptions, SolveReport, solve},
    targets::{DEFAULT_CONFIDENCE_DEGREES, Display, TargetError, bounce_targets, term_targets},
};

/// The default largest EM face size the resolution search considers, texels.
pub const DEFAULT_MAX_EM_SIZE: u32 = 128;

/// The Vulkan device as a [`TestRenderer`]: frames rendered by the runtime's compositor into an
/// RGBA32F target, uploaded once per test frame, the maps replaced between renderings.
pub struct DeviceRenderer<'a> {
    runner: &'a mut FrameRunner,
    compositing: Compositing,
    uploaded: Option<UploadedFrame>,
}

impl<'a> DeviceRenderer<'a> {
    /// Test renderings on `runner`'s device, composited as `compositing` says.
    pub fn new(runner: &'a mut FrameRunner, compositing: Compositing) -> DeviceRenderer<'a> {
        DeviceRenderer {
            runner,
            compositing,
            uploaded: None,
        }
    }
}

impl TestRenderer for DeviceRenderer<'_> {
    fn begin(&mut self, frame: &FrameInput) -> Result<(), MatrixError> {
        // The previous frame first: its drop waits for the device.
        self.uploaded = None;
        self.uploaded = Some(
            self.runner
                .upload(frame)
                .map_err(|e| MatrixError::Render(e.to_string()))?,
        );
        Ok(())
    }

    fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError> {
        let Some(uploaded) = self.uploaded.as_mut() else {
            return Err(MatrixError::Render(
                "no test frame begun; call begin first".into(),
            ));
        };
        let failed = |e: lensmap::render::RenderError| MatrixError::Render(e.to_string());
        // A layer frame holds one lens object.
        self.runner
            .replace_layers(uploaded, LensIndex::new(0), &[vec![em]])
            .map_err(failed)?;
        Ok(self
            .runner
            .render_uploaded(uploaded, self.compositing, TargetFormat::Rgba32f)
            .map_err(failed)?
            .pixels)
    }
}

/// How the EM face size is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmSize {
    /// The smallest size whose finest level is the finest level any lens pixel reads, searched
    /// up to this cap (paper: "the most detailed EM MIPMAP level actually accessed").
    Auto {
        /// Largest size considered (a power of two).
        cap: u32,
    },
    /// This size (a power of two).
    Fixed(u32),
}

/// Inference options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InferOptions {
    /// The runtime frame's options (tessellation), as the hybrid frame uses them.
    pub hybrid: HybridOptions,
    /// How the test renderings are composited.
    pub compositing: Compositing,
    /// EM face size.
    pub em_size: EmSize,
    /// Confidence threshold θ_c, radians.
    pub theta_c: f64,
    /// Add direct-image equations ([`crate::direct`]) for the texels the lens images leave
    /// unconstrained.
    pub direct_images: bool,
    /// Solver options.
    pub solve: SolveOptions,
}

impl InferOptions {
    /// The hybrid options of the bake's frames: [`InferOptions::hybrid`] with the greedy terms
    /// (the paper's Eq. 1), whatever a scene file's lens says, unless the options name path
    /// classes: then one equation per class term and texel, every class's stacked in one solve
    /// per layer as the paper stacks its two terms.
    pub fn frame_options(&self) -> HybridOptions {
        HybridOptions {
            terms: match self.hybrid.terms {
                ShadingTerms::Classes(set) => ShadingTerms::Classes(set),
                ShadingTerms::Scene | ShadingTerms::Greedy => ShadingTerms::Greedy,
            },
            ..self.hybrid
        }
    }

    /// The reference tracer's model of the bake's frames: the greedy terms, or the path classes
    /// the options name (the records the targets come from, and the references it judges by).
    pub fn model(&self) -> PathModel {
        match self.frame_options().terms {
            ShadingTerms::Classes(set) => PathModel::Classes(set),
            ShadingTerms::Scene | ShadingTerms::Greedy => PathModel::Greedy,
        }
    }
}

impl Default for InferOptions {
    fn default() -> Self {
        InferOptions {
            hybrid: HybridOptions::default(),
            compositing: Compositing::SinglePass,
            em_size: EmSize::Auto {
                cap: DEFAULT_MAX_EM_SIZE,
            },
            theta_c: DEFAULT_CONFIDENCE_DEGREES.to_radians(),
            direct_images: false,
            solve: SolveOptions::default(),
        }
    }
}

/// Why inference failed.
#[derive(Debug, thiserror::Error)]
pub enum InferError {
    /// The camera sees no pixel of the lens object.
    #[error(
        "lens \"{lens}\": the camera sees none of its pixels; pick a viewpoint that sees the lens object"
    )]
    NoLensPixels {
        /// Lens name.
        lens: String,
    },
    /// An option is out of range.
    #[error("{0}")]
    BadOption(String),
    /// Building the frame failed.
    #[error("hybrid frame: {0}")]
    Frame(String),
    /// Measuring a matrix failed.
    #[error(transparent)]
    Matrix(#[from] MatrixError),
    /// Building targets failed.
    #[error(transparent)]
    Targets(#[from] TargetError),
    /// The solve failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// What inferring one layer took.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LayerReport {
    /// The layer.
    pub layer: LayerIndex,
    /// Test renderings (all terms).
    pub renders: usize,
    /// Direct-image equations added (0 when off).
    pub direct_rows: usize,
    /// Non-zeros of each term's matrix.
    pub nonzeros: Vec<usize>,
    /// Matrix measurement time (all terms), ms.
    pub matrix_ms: f64,
    /// Target building time (all terms), ms.
    pub targets_ms: f64,
    /// The solve.
    pub solve: SolveReport,
}

/// One lens object's inferred layered EM at one camera.
#[derive(Clone, Debug)]
pub struct Inference {
    /// One cube map per layer, nearest first.
    pub maps: Vec<CubeMap>,
    /// Face size used.
    pub size: u32,
    /// Finest level read at the search cap (Auto), for the report.
    pub finest_level_at_cap: Option<usize>,
    /// Test renderings of the resolution search.
    pub search_renders: usize,
    /// Per layer.
    pub layers: Vec<LayerReport>,
    /// Building the runtime frame (tessellation, texgen), ms.
    pub frame_ms: f64,
    /// Everything, ms.
    pub total_ms: f64,
}

/// The finest MIP level any lens pixel of `layer` reads with cube maps of face size `size`:
/// ⌈levels / 4⌉ test renderings, level l lit (= 1) in channel l mod 4 of render ⌊l / 4⌋ (a
/// fragment reads two adjacent levels, which land in different channels). `None` when no pixel
/// reads the map. Returns the level and the renders made.
pub fn finest_level_read(
    renderer: &mut dyn TestRenderer,
    layer: &mut LayerFrame,
    size: u32,
) -> Result<(Option<usize>, usize), MatrixError> {
    let layout = TexelLayout::new(size);
    let zero = Arc::new(CubeMap::uniform(size, [0.0; 4]));
    renderer.begin(layer.with_em(zero.clone()))?;
    let base = renderer.render(zero)?;
    let mut renders = 1;
    for first in (0..layout.levels()).step_by(4) {
        let mut x = vec![[0.0f64; 4]; layout.len()];
        for level in first..(first + 4).min(layout.levels()) {
            for column in layout.level_columns(level) {
                x[column][level - first] = 1.0;
            }
        }
        let pixels = renderer.render(Arc::new(layout.to_cube(&x)))?;
        renders += 1;
        for c in 0..4 {
            if pixels.iter().zip(&base).any(|(p, b)| p[c] != b[c]) {
                return Ok((Some(first + c), renders));
            }
        }
    }
    Ok((None, renders))
}

/// The finest MIP level any (term, layer) frame of `frames` reads with face size `cap`
/// ([`finest_level_read`] for each), and the renders made.
pub fn finest_level_of_frames(
    renderer: &mut dyn TestRenderer,
    frames: &LayerFrames,
    layers: usize,
    cap: u32,
) -> Result<(Option<usize>, usize), MatrixError> {
    let mut finest: Option<usize> = None;
    let mut renders = 0;
    for &term in &frames.terms() {
        for layer in LayerIndex::all(layers) {
            let (level, made) = finest_level_read(renderer, &mut frames.layer(term, layer)?, cap)?;
            renders += made;
            if let Some(level) = level {
                finest = Some(finest.map_or(level, |f: usize| f.min(level)));
            }
        }
    }
    Ok((finest, renders))
}

/// One view an EM is fitted to: a camera and the reference ray tracer's intersection records of
/// the lens object at that camera.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The camera (its resolution × supersampling is the test frames' framebuffer).
    pub camera: &'a Camera,
    /// The lens object's records at that camera.
    pub records: &'a LensRecords,
}

/// Which step of an inference is starting, for progress displays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InferStep {
    /// Measuring the rendering matrices of layer `layer` of `layers`.
    Matrices {
        /// The layer.
        layer: LayerIndex,
        /// Layers in all.
        layers: usize,
    },
    /// Solving layer `layer` of `layers`.
    Solve {
        /// The layer.
        layer: LayerIndex,
        /// Layers in all.
        layers: usize,
    },
}

/// Infers one layered EM of lens object `lens` of `hybrid` (on the shells it already has) that
/// matches every view of `views` at once: each a camera and the reference ray tracer's
/// intersection records of the lens object there (the paper's simultaneous inference over
/// multiple viewpoints: one solve, the equations of every view stacked). The EM size is searched
/// on the first view. A view that sees none of the lens object adds no equations; all of them
/// seeing none is [`InferError::NoLensPixels`]. `observe` hears each step as it starts.
pub fn infer_lens(
    runner: &mut FrameRunner,
    hybrid: &HybridScene,
    lens: LensIndex,
    views: &[View<'_>],
    options: &InferOptions,
    observe: &mut dyn FnMut(InferStep),
) -> Result<Inference, InferError> {
    let start = Instant::now();
    let prepared = prepare(hybrid, lens, views, options)?;
    let mut renderer = DeviceRenderer::new(runner, options.compositing);
    // The resolution: the finest level read by any (term, layer) frame of the first view at the
    // cap.
    let (size, finest_level_at_cap, search_renders) = match options.em_size {
        EmSize::Fixed(size) => (size, None, 0),
        EmSize::Auto { cap } => {
            if !cap.is_power_of_two() {
                return Err(InferError::BadOption(format!(
                    "EM size cap {cap} is not a power of two; give e.g. 256"
                )));
            }
            let (finest, renders) = finest_level_of_frames(
                &mut renderer,
                &prepared.seen[0].1,
                prepared.layers(hybrid),
                cap,
            )?;
            let Some(level) = finest else {
                return Err(InferError::NoLensPixels {
                    lens: prepared.name,
                });
            };
            ((cap >> level).max(1), Some(level), renders)
        }
    };
    let name = prepared.name.clone();
    let frame_ms = prepared.frame_ms;
    let mut one: Vec<Option<Prepared<'_>>> = (0..hybrid.lenses().len()).map(|_| None).collect();
    one[lens.index()] = Some(prepared);
    let solved = solve_layers(
        &mut renderer,
        hybrid,
        one,
        &[],
        size,
        options,
        &mut |_, step| observe(step),
    )?;
    let Some(Some(solved)) = solved.into_iter().nth(lens.index()) else {
        unreachable!("lens {lens} was prepared, so it is solved")
    };
    // A layer no pixel reads: nothing of the lens object to fit (the one-lens API's contract).
    let Some(maps) = solved.maps.into_iter().collect::<Option<Vec<_>>>() else {
        return Err(InferError::NoLensPixels { lens: name });
    };
    Ok(Inference {
        maps,
        size,
        finest_level_at_cap,
        search_renders,
        layers: solved.layers,
        frame_ms,
        total_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

/// One lens object's inference made ready at any EM size: its test frames and targets per view.
pub struct Prepared<'v> {
    /// The lens object.
    lens: LensIndex,
    /// Its name.
    name: String,
    /// Per view that sees it: the view and its test frames.
    seen: Vec<(View<'v>, LayerFrames)>,
    /// `targets[view][term]`.
    targets: Vec<Vec<crate::targets::TermTargets>>,
    /// Building the frames, ms.
    frame_ms: f64,
    /// Building the targets, per layer, ms.
    targets_ms: f64,
}

impl Prepared<'_> {
    /// Its layer count in `hybrid`.
    fn layers(&self, hybrid: &HybridScene) -> usize {
        hybrid.lenses()[self.lens.index()].shells.len()
    }

    /// Building its frames, ms.
    pub fn frame_ms(&self) -> f64 {
        self.frame_ms
    }
}

/// Builds lens object `lens`'s test frames and targets at every view of `views` (on the shells
/// `hybrid` has). No view, or no record in any view's targets, is [`InferError::NoLensPixels`].
pub fn prepare<'v>(
    hybrid: &HybridScene,
    lens: LensIndex,
    views: &[View<'v>],
    options: &InferOptions,
) -> Result<Prepared<'v>, InferError> {
    let start = Instant::now();
    options
        .hybrid
        .validate()
        .map_err(|e| InferError::BadOption(e.to_string()))?;
    let Some(layers) = hybrid.lenses().get(lens.index()) else {
        return Err(InferError::BadOption(format!(
            "lens {lens} does not exist; the scene has {} lens objects",
            hybrid.lenses().len()
        )));
    };
    let name = hybrid.trace().lenses[lens.index()].name.clone();
    let n = layers.shells.len();
    // Per view: its test frames.
    let mut seen = Vec::new();
    for view in views {
        let (frame, _) = lensmap::hybrid::FrameBuilder::new()
            .frame(hybrid, view.camera, &options.frame_options())
            .map_err(|e| InferError::Frame(e.to_string()))?;
        let k = view.camera.supersampling.max(1);
        seen.push((*view, LayerFrames::new(&frame, lens, k)?));
    }
    let frame_ms = start.elapsed().as_secs_f64() * 1e3;
    if seen.is_empty() {
        return Err(InferError::BadOption(
            "no views to infer from; give at least one camera".into(),
        ));
    }
    let targets_start = Instant::now();
    let mut targets = Vec::new();
    for (view, frames) in &seen {
        let camera = view.camera;
        let per_term = frames
            .terms()
            .iter()
            .map(|&term| {
                let display = Display {
                    width: camera.width,
                    height: camera.height,
                    k: camera.supersampling.max(1),
                };
                match layers.layering {
                    Layering::Distance => {
                        term_targets(view.records, term, &layers.shells, display, options.theta_c)
                    }
                    Layering::Bounce => {
                        bounce_targets(view.records, term, display, options.theta_c)
                    }
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        targets.push(per_term);
    }
    let targets_ms = targets_start.elapsed().as_secs_f64() * 1e3 / n.max(1) as f64;
    if targets.iter().flatten().all(|t| t.pixels_with_records == 0) {
        return Err(InferError::NoLensPixels { lens: name });
    }
    Ok(Prepared {
        lens,
        name,
        seen,
        targets,
        frame_ms,
        targets_ms,
    })
}

/// What [`solve_layers`] inferred for one lens object.
pub struct SolvedLens {
    /// Per layer, the inferred map; `None` for a layer no pixel of any view reads (no equation
    /// to fit).
    pub maps: Vec<Option<CubeMap>>,
    /// Per layer, nearest first. A shared layer's solve is timed at the member that solved it
    /// (the others report its iterations and residual with 0 ms).
    pub layers: Vec<LayerReport>,
}

/// Infers the layered EMs of every lens object of `prepared` (`prepared[lens]`, one entry per
/// lens object of `hybrid`; `None`: not inferred) at face size
/// `size`, one solve per layer on that lens object's equations (all its views, both terms), except
/// each layer of `shared` — a group of (lens, layer) with one shell and one EM origin, the
/// hybrid-rendering paper's "more equations … simultaneously solving for a single EM" — which is
/// solved once on the equations of every member and given to all of them. Returns per lens
/// object what was inferred (`None` where `prepared` had none). `observe` hears each step with
/// its lens object.
pub fn solve_layers(
    renderer: &mut DeviceRenderer<'_>,
    hybrid: &HybridScene,
    prepared: Vec<Option<Prepared<'_>>>,
    shared: &[Vec<LayerRef>],
    size: u32,
    options: &InferOptions,
    observe: &mut dyn FnMut(LensIndex, InferStep),
) -> Result<Vec<Option<SolvedLens>>, InferError> {
    check_solve_inputs(hybrid, &prepared, shared, size)?;
    let layout = TexelLayout::new(size);
    let smoothness = Smoothness::new(&layout);
    let mut out: Vec<Option<SolvedLens>> = prepared
        .iter()
        .enumerate()
        .map(|(lens, p)| {
            p.as_ref().map(|_| {
                let n = hybrid.lenses()[lens].shells.len();
                SolvedLens {
                    maps: vec![None; n],
                    layers: Vec::with_capacity(n),
                }
            })
        })
        .collect();
    // Per lens object: a device that needed power-of-two digits once keeps them for that lens
    // object's remaining matrices.
    let mut encodings = vec![DigitEncoding::Integers; prepared.len()];
    for (lens, lens_prepared) in LensIndex::all(prepared.len()).zip(&prepared) {
        if lens_prepared.is_none() {
            continue;
        }
        let n = hybrid.lenses()[lens.index()].shells.len();
        for layer in LayerIndex::all(n) {
            let at = lens.layer(layer);
            let group = shared
                .iter()
                .find(|group| group.contains(&at))
                .cloned()
                .unwrap_or_else(|| vec![at]);
            // A shared layer is solved at its first inferred member.
            let first = group
                .iter()
                .copied()
                .find(|m| prepared.get(m.lens.index()).is_some_and(Option::is_some));
            if first != Some(at) {
                continue;
            }
            observe(lens, InferStep::Matrices { layer, layers: n });
            let matrix_start = Instant::now();
            let members = measure_group(renderer, &prepared, &group, size, &mut encodings)?;
            let matrix_ms = matrix_start.elapsed().as_secs_f64() * 1e3;
            let seen = members
                .iter()
                .any(|m| m.matrices.iter().flatten().any(|m| m.nnz() > 0));
            let solved = if seen {
                let group = Group {
                    members: &members,
                    owner: group[0],
                    solver: at,
                };
                let observe_solve = &mut || observe(lens, InferStep::Solve { layer, layers: n });
                Some(solve_group(
                    hybrid,
                    &group,
                    &layout,
                    &smoothness,
                    options,
                    observe_solve,
                )?)
            } else {
                None
            };
            for member in &members {
                let Some(Some(solved_lens)) = out.get_mut(member.prepared.lens.index()) else {
                    unreachable!("every member with matrices was prepared")
                };
                solved_lens.maps[member.layer.index()] = solved.as_ref().map(|s| s.map.clone());
                solved_lens.layers.push(member.report(
                    member.prepared.lens == lens,
                    matrix_ms,
                    solved.as_ref(),
                ));
            }
        }
    }
    for solved in out.iter_mut().flatten() {
        solved.layers.sort_by_key(|l| l.layer);
    }
    Ok(out)
}

/// Checks the inputs of [`solve_layers`]: a power-of-two size, `prepared[lens]` for each lens
/// object, and shared groups of existing layers with one shell and one EM origin.
fn check_solve_inputs(
    hybrid: &HybridScene,
    prepared: &[Option<Prepared<'_>>],
    shared: &[Vec<LayerRef>],
    size: u32,
) -> Result<(), InferError> {
    if !size.is_power_of_two() {
        return Err(InferError::BadOption(format!(
            "EM size {size} is not a power of two; give e.g. 128"
        )));
    }
    let misplaced = prepared
        .iter()
        .enumerate()
        .any(|(i, p)| p.as_ref().is_some_and(|p| p.lens.index() != i));
    if prepared.len() != hybrid.lenses().len() || misplaced {
        return Err(InferError::BadOption(format!(
            "{} prepared lens objects for a scene of {}; give prepared[lens] for each lens object",
            prepared.len(),
            hybrid.lenses().len()
        )));
    }
    for group in shared {
        let layer_of = |&LayerRef { lens, layer }: &LayerRef| {
            let layer = layer.index();
            hybrid
                .lenses()
                .get(lens.index())
                .filter(|l| layer < l.shells.len() && layer < l.em_origins.len())
                .map(|l| (l.shells[layer], l.em_origins[layer]))
        };
        let first = group.first().and_then(layer_of);
        if first.is_none() || group.iter().any(|m| layer_of(m) != first) {
            return Err(InferError::BadOption(format!(
                "shared layer {group:?}: give (lens, layer) pairs of the scene with one shell and one EM origin"
            )));
        }
    }
    Ok(())
}

/// One inferred member of a layer group (a layer alone, or a shared layer's members) and its
/// rendering matrices, `matrices[view][term]`.
struct MemberMatrices<'p, 'v> {
    prepared: &'p Prepared<'v>,
    layer: LayerIndex,
    matrices: Vec<Vec<RenderingMatrix>>,
}

impl MemberMatrices<'_, '_> {
    /// The member's layer report: the solve's figures, its time and the group's matrix time
    /// and direct rows only at the member that solved it (`solver`).
    fn report(&self, solver: bool, matrix_ms: f64, solved: Option<&SolvedMap>) -> LayerReport {
        let solve = solved.map_or_else(SolveReport::default, |s| s.report.clone());
        LayerReport {
            layer: self.layer,
            renders: self.matrices.iter().flatten().map(|m| m.renders).sum(),
            direct_rows: match solved {
                Some(s) if solver => s.direct_rows,
                _ => 0,
            },
            nonzeros: self
                .matrices
                .iter()
                .flatten()
                .map(RenderingMatrix::nnz)
                .collect(),
            matrix_ms: if solver { matrix_ms } else { 0.0 },
            targets_ms: self.prepared.targets_ms,
            solve: SolveReport {
                ms: if solver { solve.ms } else { 0.0 },
                ..solve
            },
        }
    }
}

/// The rendering matrices of every inferred member of `group`, at every view and term; `encodings[lens]` is the digit encoding each lens object's next matrix tries
/// first, updated as matrices are measured.
fn measure_group<'p, 'v>(
    renderer: &mut DeviceRenderer<'_>,
    prepared: &'p [Option<Prepared<'v>>],
    group: &[LayerRef],
    size: u32,
    encodings: &mut [DigitEncoding],
) -> Result<Vec<MemberMatrices<'p, 'v>>, InferError> {
    let mut members = Vec::new();
    for &LayerRef {
        lens: member_lens,
        layer: member_layer,
    } in group
    {
        let Some(Some(p)) = prepared.get(member_lens.index()) else {
            continue;
        };
        let mut matrices: Vec<Vec<RenderingMatrix>> = Vec::new();
        for (view, frames) in &p.seen {
            let k = view.camera.supersampling.max(1);
            matrices.push(
                frames
                    .terms()
                    .iter()
                    .map(|&term| {
                        let encoding = &mut encodings[member_lens.index()];
                        let options = MeasureOptions {
                            digits: Digits::Starting(*encoding),
                            ..MeasureOptions::new(size, k)
                        };
                        let matrix = RenderingMatrix::measure(
                            renderer,
                            &mut frames.layer(term, member_layer)?,
                            &options,
                        )?;
                        *encoding = matrix.encoding;
                        Ok::<_, InferError>(matrix)
                    })
                    .collect::<Result<_, _>>()?,
            );
        }
        members.push(MemberMatrices {
            prepared: p,
            layer: member_layer,
            matrices,
        });
    }
    Ok(members)
}

/// A layer group to solve: its members' matrices, the layer whose map and EM origin the group
/// uses (the first member), and the one solved at (the first inferred member).
struct Group<'g, 'p, 'v> {
    members: &'g [MemberMatrices<'p, 'v>],
    owner: LayerRef,
    solver: LayerRef,
}

/// A layer group's solution.
struct SolvedMap {
    map: CubeMap,
    report: SolveReport,
    direct_rows: usize,
}

/// Solves one layer group on every member's equations (all views and terms), with direct-image
/// equations when asked; `observe` hears the solve start.
fn solve_group(
    hybrid: &HybridScene,
    group: &Group<'_, '_, '_>,
    layout: &TexelLayout,
    smoothness: &Smoothness,
    options: &InferOptions,
    observe: &mut dyn FnMut(),
) -> Result<SolvedMap, InferError> {
    let LayerRef { lens, layer } = group.solver;
    // The layer's current (projected) EM at this size: CG's start (where no pixel constrains a
    // texel, few iterations move it, and the projection is a better guess there than zero) and
    // the direct images' values.
    let current = hybrid.lenses()[lens.index()]
        .maps
        .first()
        .and_then(|maps| maps.get(layer.index()))
        .map(|current| resampled(current, layout.size));
    // Direct images from the map's own origin: the owner's view, with every member's records
    // telling which texels the lens images already constrain.
    let direct = match (&current, options.direct_images) {
        (Some(projected), true) => {
            let records: Vec<&LensRecords> = group
                .members
                .iter()
                .flat_map(|m| m.prepared.seen.iter().map(|(v, _)| v.records))
                .collect();
            let owner = group.owner;
            let owner_layers = &hybrid.lenses()[owner.lens.index()];
            let at = crate::direct::DirectLayer {
                trace: hybrid.trace(),
                lens: owner.lens,
                origin: owner_layers.em_origins[owner.layer.index()],
                shells: &owner_layers.shells,
                layer: owner.layer,
            };
            Some(crate::direct::direct_equations(
                &at, layout, projected, &records,
            ))
        }
        _ => None,
    };
    let mut equations: Vec<Equations<'_>> = group
        .members
        .iter()
        .flat_map(|member| {
            member
                .matrices
                .iter()
                .zip(&member.prepared.targets)
                .flat_map(move |(matrices, targets)| {
                    matrices.iter().zip(targets).map(move |(m, t)| Equations {
                        a: &m.a,
                        b: &t.layers[member.layer.index()],
                        confidence: &t.confidence,
                    })
                })
        })
        .collect();
    let mut direct_rows = 0;
    if let Some(direct) = &direct {
        equations.push(Equations {
            a: &direct.a,
            b: &direct.b,
            confidence: &direct.confidence,
        });
        direct_rows = direct.b.len();
    }
    let start = current
        .as_ref()
        .map(|current| layout.from_cube(current))
        .unwrap_or_else(|| vec![[0.0; 4]; layout.len()]);
    observe();
    let (x, report) = solve(&equations, layout, smoothness, &start, &options.solve)?;
    Ok(SolvedMap {
        map: layout.to_cube(&x),
        report,
        direct_rows,
    })
}

/// `cube` at face size `size`: itself when the sizes agree, else level 0 sampled bilinearly at
/// the new texel centres and the chain box-filtered.
fn resampled(cube: &CubeMap, size: u32) -> CubeMap {
    if cube.size == size {
        return cube.clone();
    }
    CubeMap::from_fn(size, |direction| {
        sample_cube_trilinear(cube, direction, 0.0).map(|v| v as f32)
    })
}
