// A stable two-level exclusive prefix sum over vec4<u32> counts, shared by the tessellation and
// the draw list (tessellate.wgsl, drawlist.wgsl). The including shader declares `counts` (per
// element its counts, replaced by its exclusive prefix within its block), `block_sums` (per block
// of SCAN_BLOCK elements its total, replaced by its exclusive prefix), `load(word)` of its control
// words, CONTROL_SCAN_N (the word holding the element count) and SCAN_BLOCK (256). The passes:
// `cs_scan_blocks` over the blocks, then `cs_scan_top` as one workgroup; `scanned(i)` is then
// element i's exclusive prefix over the whole scan.

var<workgroup> scan_scratch: array<vec4<u32>, 256>;
var<workgroup> scan_length: u32;

// The exclusive prefix of `value` over the workgroup (lane order); the total is left in
// scan_scratch[SCAN_BLOCK - 1].
fn workgroup_exclusive(lane: u32, value: vec4<u32>) -> vec4<u32> {
    workgroupBarrier();
    scan_scratch[lane] = value;
    for (var d = 1u; d < SCAN_BLOCK; d *= 2u) {
        workgroupBarrier();
        var v = scan_scratch[lane];
        if lane >= d {
            v += scan_scratch[lane - d];
        }
        workgroupBarrier();
        scan_scratch[lane] = v;
    }
    workgroupBarrier();
    return scan_scratch[lane] - value;
}

// Each block's exclusive prefix in place, and its total.
@compute @workgroup_size(256)
fn cs_scan_blocks(
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(workgroup_id) group: vec3<u32>,
) {
    let n = load(CONTROL_SCAN_N);
    let i = group.x * SCAN_BLOCK + local.x;
    var value = vec4<u32>(0u);
    if i < n {
        value = counts[i];
    }
    let prefix = workgroup_exclusive(local.x, value);
    if i < n {
        counts[i] = prefix;
    }
    if local.x == SCAN_BLOCK - 1u {
        block_sums[group.x] = prefix + value;
    }
}

// The blocks' exclusive prefix in place: one workgroup, a block of totals at a time.
@compute @workgroup_size(256)
fn cs_scan_top(@builtin(local_invocation_id) local: vec3<u32>) {
    if local.x == 0u {
        scan_length = load(CONTROL_SCAN_N);
    }
    let n = workgroupUniformLoad(&scan_length);
    let blocks = (n + SCAN_BLOCK - 1u) / SCAN_BLOCK;
    var carry = vec4<u32>(0u);
    for (var base = 0u; base < blocks; base += SCAN_BLOCK) {
        let i = base + local.x;
        var value = vec4<u32>(0u);
        if i < blocks {
            value = block_sums[i];
        }
        let prefix = workgroup_exclusive(local.x, value);
        if i < blocks {
            block_sums[i] = prefix + carry;
        }
        carry += scan_scratch[SCAN_BLOCK - 1u];
    }
}

// An element's exclusive prefix over the whole scan.
fn scanned(i: u32) -> vec4<u32> {
    return counts[i] + block_sums[i / SCAN_BLOCK];
}
