// The GPU tessellation's control words, shared by every pass that reads or writes them
// (tessellate.wgsl, the tracer's level pass in vertex_paths.wgsl, texgen.wgsl, drawlist.wgsl) and
// generated into Rust by shaders/build.rs (`lensmap_shaders::tessellate::CONTROL_*`): ranges,
// dispatch arguments, counts and statistics in one storage buffer of CONTROL_WORDS words.
const CONTROL_LEVEL_LO: u32 = 0u;
const CONTROL_LEVEL_HI: u32 = 1u;
const CONTROL_NEXT_HI: u32 = 2u;
const CONTROL_VERTEX_LO: u32 = 3u;
const CONTROL_VERTEX_HI: u32 = 4u;
const CONTROL_VERTICES: u32 = 5u;
const CONTROL_NEXT_VERTICES: u32 = 6u;
const CONTROL_EDGES: u32 = 7u;
const CONTROL_NEXT_EDGES: u32 = 8u;
const CONTROL_SCAN_N: u32 = 9u;
const CONTROL_LEVEL: u32 = 10u;
const CONTROL_OUTPUT: u32 = 11u;
const CONTROL_DISPATCH_TRACE: u32 = 12u;
const CONTROL_DISPATCH_ELEMENTS: u32 = 15u;
const CONTROL_DISPATCH_BLOCKS: u32 = 18u;
const CONTROL_INPUT_VERTICES: u32 = 21u;
const STAT_FRONT: u32 = 24u;
const STAT_BACK: u32 = 25u;
const STAT_SPLITS: u32 = 26u; // 26, 27, 28: 1-to-2, 1-to-3, 1-to-4
const STAT_CREATED: u32 = 29u;
const STAT_REQUESTS: u32 = 30u;
const STAT_MAX_DEPTH_REACHED: u32 = 31u;
const STAT_AT_MAX_DEPTH: u32 = 32u;
const STAT_BUDGET: u32 = 33u;
const STAT_OCCLUDED: u32 = 34u;
const STAT_T_JUNCTION_LEAVES: u32 = 35u;
const STAT_T_JUNCTION_VERTICES: u32 = 36u;
// The path classes the tracer follows per vertex (engine/src/trace/classes.rs), 0 for the two
// greedy terms; then per class two words: its events (bits 0-7) and whether its path goes on
// greedily after them (bit 8), and its reflections (bit i set when event i reflects). Written by
// the host for every object: a vertex record holds max(classes, 2) terms (record_terms).
const CONTROL_CLASSES: u32 = 37u;
const CONTROL_CLASS_WORDS: u32 = 38u;
const MAX_CLASSES: u32 = 16u;
// The most vertices this tessellation may hold: the capacity, or the frame's vertex budget left
// (at least the input's), whichever is smaller; set by cs_begin.
const CONTROL_VERTEX_LIMIT: u32 = 70u;
// The frame's vertex budget left: written by the host for the frame's first lens object (and
// where the host counts the budget itself), kept between the objects of a frame, and lowered by
// each object's vertices in cs_leaves_begin, so that the frame's lens objects share one budget
// in order with no count read back.
const CONTROL_FRAME_BUDGET: u32 = 71u;
// This object's share of it: the frame's budget left, or its input vertices if more; set by
// cs_begin (the host compares it with the capacity to tell a budget stop from a full buffer).
const CONTROL_OBJECT_BUDGET: u32 = 72u;
// Words in the control buffer.
const CONTROL_WORDS: u32 = 73u;

// The tracer's counters (a buffer of their own, added to with atomics).
const COUNTER_PRIMARY_RAYS: u32 = 0u;
const COUNTER_SECONDARY_RAYS: u32 = 1u;
const COUNTER_TRIANGLE_TESTS: u32 = 2u;
const COUNTERS: u32 = 3u;

// Invocations per workgroup of the element passes, and elements per block of the prefix sum.
const WORKGROUP: u32 = 64u;
const SCAN_BLOCK: u32 = 256u;
