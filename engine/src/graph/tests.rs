//! Plans checked without a GPU.

use super::*;

/// Draws are numbers, programs and categories names.
type TestPass = Pass<u32, &'static str, &'static str>;

fn draw(
    name: &str,
    colour: ImageId,
    load: LoadOp,
    depth: Option<(ImageId, LoadOp, bool)>,
    draws: usize,
) -> TestPass {
    Pass {
        name: name.into(),
        category: "test",
        side_effect: false,
        kind: PassKind::Draw {
            program: "p",
            colour: ColourAttachment {
                image: colour,
                load,
                store: StoreOp::Store,
                blend: Blend::FrontToBackOver,
                write_mask: ColourMask::RGBA,
            },
            depth: depth.map(|(image, load, write)| DepthAttachment {
                image,
                load,
                store: StoreOp::Store,
                test: Some(CompareOp::Less),
                write,
            }),
            cull: Cull::Back,
            sampled: Vec::new(),
            storage: Vec::new(),
            draws: (0..draws as u32).collect(),
        },
    }
}

fn frame() -> (
    Graph<u32, &'static str, &'static str>,
    ImageId,
    ImageId,
    BufferId,
) {
    let mut g = Graph::new();
    let colour = g.image("colour", Format::Rgba32Float, 8, 8);
    let depth = g.image("depth", Format::Depth32Float, 8, 8);
    let readback = g.buffer("readback", 8 * 8 * 16);
    (g, colour, depth, readback)
}

fn readback(colour: ImageId, buffer: BufferId) -> TestPass {
    Pass {
        name: "readback".into(),
        category: "readback",
        side_effect: true,
        kind: PassKind::Readback {
            image: colour,
            buffer,
        },
    }
}

#[test]
fn consecutive_loading_passes_share_one_rendering_instance() {
    let (mut g, colour, depth, buffer) = frame();
    g.add_pass(draw(
        "env",
        colour,
        LoadOp::Clear([0.0; 4]),
        Some((depth, LoadOp::Clear([1.0; 4]), true)),
        2,
    ));
    g.add_pass(draw(
        "layer0",
        colour,
        LoadOp::Load,
        Some((depth, LoadOp::Load, false)),
        1,
    ));
    g.add_pass(draw(
        "layer1",
        colour,
        LoadOp::Load,
        Some((depth, LoadOp::Load, false)),
        1,
    ));
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().unwrap();
    assert_eq!(plan.steps.len(), 4);
    assert_eq!(plan.rendering_instances(), 1);
    assert!(plan.steps[0].begin.is_some() && plan.steps[2].end);
    // Two transitions out of UNDEFINED up front, one to TRANSFER_SRC for the copy, none between
    // the blending passes (rasterization order covers them).
    let barriers: Vec<_> = plan.steps.iter().map(|s| s.barriers.len()).collect();
    assert_eq!(barriers, vec![2, 0, 0, 1]);
    let copy = plan.steps[3].barriers[0];
    assert_eq!(
        (copy.old_layout, copy.new_layout),
        (Layout::ColourAttachment, Layout::TransferSrc)
    );
    assert_eq!(
        (copy.src, copy.dst),
        (Access::ColourAttachment, Access::TransferRead)
    );
}

#[test]
fn a_changed_attachment_set_starts_a_new_instance_with_a_barrier() {
    let (mut g, colour, depth, buffer) = frame();
    g.add_pass(draw(
        "env",
        colour,
        LoadOp::Clear([0.0; 4]),
        Some((depth, LoadOp::Clear([1.0; 4]), true)),
        1,
    ));
    g.add_pass(draw("no-depth", colour, LoadOp::Load, None, 1));
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().unwrap();
    assert_eq!(plan.rendering_instances(), 2);
    let second = &plan.steps[1].barriers;
    assert_eq!(second.len(), 1, "{plan}");
    assert_eq!(second[0].old_layout, Layout::ColourAttachment);
    assert_eq!(
        (second[0].src, second[0].dst),
        (Access::ColourAttachment, Access::ColourAttachment)
    );
}

#[test]
fn unused_outputs_and_empty_draw_lists_are_culled() {
    let (mut g, colour, depth, buffer) = frame();
    let scratch = g.image("scratch", Format::Rgba8Unorm, 8, 8);
    g.add_pass(draw(
        "env",
        colour,
        LoadOp::Clear([0.0; 4]),
        Some((depth, LoadOp::Clear([1.0; 4]), true)),
        1,
    ));
    g.add_pass(draw("unread", scratch, LoadOp::Clear([0.0; 4]), None, 1));
    g.add_pass(draw(
        "empty",
        colour,
        LoadOp::Load,
        Some((depth, LoadOp::Load, false)),
        0,
    ));
    g.add_pass(draw(
        "layer",
        colour,
        LoadOp::Load,
        Some((depth, LoadOp::Load, false)),
        1,
    ));
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().unwrap();
    let names: Vec<_> = plan.steps.iter().map(|s| s.pass.name.as_str()).collect();
    assert_eq!(names, ["env", "layer", "readback"]);
    assert_eq!(
        plan.culled,
        vec![
            ("unread".to_string(), CullReason::OutputUnused),
            ("empty".to_string(), CullReason::EmptyDrawList)
        ]
    );
    // A pass whose clear is overwritten by a later clear is dead too.
    let (mut g, colour, _, buffer) = frame();
    g.add_pass(draw(
        "first-clear",
        colour,
        LoadOp::Clear([0.0; 4]),
        None,
        1,
    ));
    g.add_pass(draw(
        "second-clear",
        colour,
        LoadOp::Clear([0.0; 4]),
        None,
        1,
    ));
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().unwrap();
    assert_eq!(
        plan.culled,
        vec![("first-clear".to_string(), CullReason::OutputUnused)]
    );
}

#[test]
fn a_clearing_pass_with_no_draws_is_kept() {
    let (mut g, colour, _, buffer) = frame();
    g.add_pass(draw("clear", colour, LoadOp::Clear([0.0; 4]), None, 0));
    g.add_pass(readback(colour, buffer));
    assert_eq!(g.compile().unwrap().steps.len(), 2);
}

#[test]
fn declaration_errors_are_values() {
    let (mut g, colour, depth, buffer) = frame();
    g.add_pass(draw("a", colour, LoadOp::Load, None, 1));
    g.add_pass(readback(colour, buffer));
    assert_eq!(
        g.compile(),
        Err(GraphError::ReadBeforeWrite {
            pass: "a".into(),
            image: "colour".into()
        })
    );

    let (mut g, colour, _, _) = frame();
    g.add_pass(draw("a", colour, LoadOp::Clear([0.0; 4]), None, 1));
    g.add_pass(draw("a", colour, LoadOp::Load, None, 1));
    assert_eq!(g.compile(), Err(GraphError::DuplicatePass("a".into())));

    let (mut g, colour, depth2, _) = frame();
    g.add_pass(draw(
        "swapped",
        depth2,
        LoadOp::Clear([0.0; 4]),
        Some((colour, LoadOp::Clear([1.0; 4]), true)),
        1,
    ));
    assert!(matches!(
        g.compile(),
        Err(GraphError::BadAttachment { role: "colour", .. })
    ));
    let _ = depth;

    let (mut g, colour, _, _) = frame();
    g.add_pass(draw(
        "unknown",
        ImageId(99),
        LoadOp::Clear([0.0; 4]),
        None,
        1,
    ));
    let _ = colour;
    assert!(matches!(
        g.compile(),
        Err(GraphError::UnknownResource { kind: "image", .. })
    ));
}

#[test]
fn imported_images_are_readable_and_need_no_barrier() {
    let (mut g, colour, _, buffer) = frame();
    let texture = g.import_image("em", Format::Rgba32Float, 4, 4);
    let mut pass = draw("sample", colour, LoadOp::Clear([0.0; 4]), None, 1);
    if let PassKind::Draw { sampled, .. } = &mut pass.kind {
        sampled.push(texture);
    }
    g.add_pass(pass);
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().unwrap();
    assert_eq!(
        plan.steps[0].barriers.len(),
        1,
        "only the colour target's transition:\n{plan}"
    );
    let table = plan.to_string();
    assert!(table.contains("colour: undefined->colour"), "{table}");
}

/// A frame ending in a filter into an external image and its hand-back: the colour target goes
/// to shader-read for the filter; the external image leaves the owner's layout (kept, even though
/// the filter discards its contents: the owner's word is what the barrier must match) for a
/// colour attachment, waiting for the owner's earlier work; and goes back to the owner's layout.
/// Without the export nothing reads the filter, so both are culled; exporting an image the frame
/// made is an error.
#[test]
fn an_external_image_is_filtered_into_and_handed_back() {
    let (mut g, colour, depth, _) = frame();
    let host = g.external_image("host", Format::Bgra8Srgb, 4, 4);
    g.add_pass(draw(
        "env",
        colour,
        LoadOp::Clear([0.0; 4]),
        Some((depth, LoadOp::Clear([1.0; 4]), true)),
        1,
    ));
    let mut filter = draw("filter", host, LoadOp::DontCare, None, 1);
    if let PassKind::Draw { sampled, .. } = &mut filter.kind {
        sampled.push(colour);
    }
    let mut unexported = g.clone();
    unexported.add_pass(filter.clone());
    let culled = unexported.compile().unwrap();
    assert!(culled.steps.is_empty(), "nothing is read:\n{culled}");

    g.add_pass(filter);
    let export = |image| Pass {
        name: "export".into(),
        category: "export",
        side_effect: true,
        kind: PassKind::Export { image },
    };
    let mut bad = g.clone();
    bad.add_pass(export(colour));
    assert!(matches!(
        bad.compile(),
        Err(GraphError::NotExternal { ref image, .. }) if image == "colour"
    ));

    g.add_pass(export(host));
    let plan = g.compile().unwrap();
    let names: Vec<&str> = plan.steps.iter().map(|s| s.pass.name.as_str()).collect();
    assert_eq!(names, ["env", "filter", "export"], "{plan}");
    let filter_barriers = &plan.steps[1].barriers;
    assert!(filter_barriers.contains(&Barrier {
        image: host,
        old_layout: Layout::External,
        new_layout: Layout::ColourAttachment,
        src: Access::External,
        dst: Access::ColourAttachment,
    }));
    assert!(filter_barriers.contains(&Barrier {
        image: colour,
        old_layout: Layout::ColourAttachment,
        new_layout: Layout::ShaderRead,
        src: Access::ColourAttachment,
        dst: Access::FragmentSample,
    }));
    assert_eq!(
        plan.steps[2].barriers,
        [Barrier {
            image: host,
            old_layout: Layout::ColourAttachment,
            new_layout: Layout::External,
            src: Access::ColourAttachment,
            dst: Access::External,
        }]
    );
    assert_eq!(plan.steps[1].begin.map(|i| i.colour.0), Some(host));
    let table = plan.to_string();
    assert!(table.contains("host: colour->external"), "{table}");
}

#[test]
fn a_compute_pass_runs_first_and_the_draws_that_read_its_buffers_wait_for_it() {
    let (mut g, colour, depth, buffer) = frame();
    let part = g.buffer("part", 64);
    let unread = g.buffer("unread", 64);
    let compute = |name: &str, writes: Vec<BufferId>, side_effect: bool| TestPass {
        name: name.into(),
        category: "compute",
        side_effect,
        kind: PassKind::Compute {
            dispatches: vec![7],
            buffers: writes.iter().map(|&b| (b, Access::ComputeWrite)).collect(),
        },
    };
    g.add_pass(compute("make", vec![part], false));
    // Nothing reads it and it has no side effect: culled.
    g.add_pass(compute("idle", vec![unread], false));
    g.add_pass(draw(
        "clear",
        colour,
        LoadOp::Clear([0.0; 4]),
        Some((depth, LoadOp::Clear([1.0, 0.0, 0.0, 0.0]), true)),
        1,
    ));
    let mut reader = draw(
        "read",
        colour,
        LoadOp::Load,
        Some((depth, LoadOp::Load, true)),
        1,
    );
    if let PassKind::Draw { storage, .. } = &mut reader.kind {
        storage.push(part);
    }
    g.add_pass(reader);
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().expect("compiles");
    let names: Vec<&str> = plan.steps.iter().map(|s| s.pass.name.as_str()).collect();
    assert_eq!(names, ["make", "clear", "read", "readback"]);
    assert_eq!(
        plan.culled,
        vec![("idle".to_string(), CullReason::OutputUnused)]
    );
    // The compute step is outside rendering; the instance that reads its buffer waits for it
    // once, on its first step.
    assert!(plan.steps[0].begin.is_none() && !plan.steps[0].end);
    assert_eq!(
        plan.steps[1].buffer_barriers,
        vec![BufferBarrier {
            buffer: part,
            src: Access::ComputeWrite,
            dst: Access::VertexStorageRead,
        }]
    );
    assert!(plan.steps[2..].iter().all(|s| s.buffer_barriers.is_empty()));
    assert!(plan.to_string().contains("part: compute->vertex"));
    // A compute pass kept for its side effect stays even with no reader.
    let (mut g, colour, _, buffer) = frame();
    let counts = g.buffer("counts", 64);
    g.add_pass(compute("counted", vec![counts], true));
    g.add_pass(draw("clear", colour, LoadOp::Clear([0.0; 4]), None, 1));
    g.add_pass(readback(colour, buffer));
    let plan = g.compile().expect("compiles");
    assert_eq!(plan.steps[0].pass.name, "counted");
    assert!(plan.steps.iter().all(|s| s.buffer_barriers.is_empty()));
}

/// A chain of compute and transfer passes over shared buffers: the graph places a barrier before
/// each use that must wait (a read after a write, a write after reads or a write), none before a
/// second read, one from the work submitted before on a kept buffer's first use, and the host's
/// read after the last copy.
#[test]
fn compute_passes_wait_for_what_they_read_and_what_they_overwrite() {
    let mut g: Graph<u32, &str, &str> = Graph::new();
    let control = g.kept_buffer("control", 16);
    let data = g.buffer("data", 64);
    let host = g.kept_buffer("host", 16);
    let pass = |name: &str, buffers: Vec<(BufferId, Access)>| TestPass {
        name: name.into(),
        category: "compute",
        side_effect: true,
        kind: PassKind::Compute {
            dispatches: vec![0],
            buffers,
        },
    };
    g.add_pass(pass("update", vec![(control, Access::TransferWrite)]));
    g.add_pass(pass(
        "write",
        vec![(control, Access::ComputeRead), (data, Access::ComputeWrite)],
    ));
    g.add_pass(pass(
        "read",
        vec![(data, Access::ComputeRead), (control, Access::IndirectRead)],
    ));
    g.add_pass(pass("read again", vec![(data, Access::ComputeRead)]));
    g.add_pass(pass(
        "rewrite",
        vec![
            (data, Access::ComputeWrite),
            (control, Access::ComputeWrite),
        ],
    ));
    g.add_pass(pass(
        "copy",
        vec![
            (control, Access::TransferRead),
            (host, Access::TransferWrite),
        ],
    ));
    g.add_pass(TestPass {
        name: "host".into(),
        category: "host",
        side_effect: false,
        kind: PassKind::HostRead {
            buffers: vec![host],
        },
    });
    let plan = g.compile().expect("compiles");
    let barriers: Vec<Vec<(BufferId, Access, Access)>> = plan
        .steps
        .iter()
        .map(|s| {
            s.buffer_barriers
                .iter()
                .map(|b| (b.buffer, b.src, b.dst))
                .collect()
        })
        .collect();
    use Access::*;
    assert_eq!(
        barriers,
        vec![
            // The kept control buffer waits for the work before.
            vec![(control, Earlier, TransferWrite)],
            // The frame's data buffer waits for nothing.
            vec![(control, TransferWrite, ComputeRead)],
            vec![
                (data, ComputeWrite, ComputeRead),
                (control, TransferWrite, IndirectRead)
            ],
            // A second read of the same kind: no barrier.
            vec![],
            // Writes wait for every kind of read since the last write.
            vec![
                (data, ComputeRead, ComputeWrite),
                (control, ComputeRead, ComputeWrite),
                (control, IndirectRead, ComputeWrite),
            ],
            vec![
                (control, ComputeWrite, TransferRead),
                (host, Earlier, TransferWrite)
            ],
            vec![(host, TransferWrite, HostRead)],
        ]
    );
    let table = plan.to_string();
    assert!(table.contains("host: transfer->host"), "{table}");
    assert!(table.contains("transfer"), "{table}");
    assert!(table.contains("host read"), "{table}");
}
