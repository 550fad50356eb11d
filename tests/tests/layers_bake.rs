//! The bake directory format: bit-exact round trips, deterministic bytes, atomic replacement,
//! and one test per way a bake can be wrong (each must fail with one line naming the file, the
//! field or EXR part, and a fix). Every test works in its own fresh folder.

/// Named `layers_bake` so that `cargo test -p lensmap-tests layers` selects these tests.
mod layers_bake {
    use std::fs;
    use std::path::{Path, PathBuf};
    use std::sync::Arc;

    use glam::{DVec2, DVec3, Vec3};
    use lensmap::cubemap::CubeMap;
    use lensmap::index::{LayerIndex, LensIndex};
    use lensmap::layers::bake::{
        ALPHA_TOLERANCE, MANIFEST_FILE_NAME, map_file_name, read_cube_map_exr, write_cube_map_exr,
    };
    use lensmap::layers::{Bake, BakeError, BakedLens, LayerShell, Layering, Manifest};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A fresh, empty folder for one test, holding the bake directory `bake` (returned).
    fn fresh(test: &str) -> PathBuf {
        let root =
            std::env::temp_dir().join(format!("lensmap-layers-bake-{}-{test}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        fs::create_dir_all(&root).unwrap();
        root.join("bake")
    }

    /// A cube map whose every level holds independent random premultiplied texels (not a box
    /// filter of level 0, so a format that regenerated mips would fail the round trip), with
    /// exact 0, 1, −0 and subnormal values sprinkled in.
    fn random_cube(rng: &mut Pcg64, size: u32) -> CubeMap {
        let levels = (0..CubeMap::full_chain_levels(size))
            .map(|level| {
                let n = ((size >> level).max(1) as usize).pow(2);
                std::array::from_fn(|_| {
                    (0..n)
                        .map(|i| {
                            let alpha: f32 = match i % 7 {
                                0 => 0.0,
                                1 => 1.0,
                                _ => rng.r#gen(),
                            };
                            let mut texel = [
                                alpha * rng.gen_range(0.0..4.0f32),
                                alpha * rng.gen_range(0.0..4.0f32),
                                alpha * rng.gen_range(0.0..4.0f32),
                                alpha,
                            ];
                            if i % 11 == 3 {
                                texel[0] = -0.0;
                                texel[1] = f32::MIN_POSITIVE / 8.0;
                            }
                            texel
                        })
                        .collect()
                })
            })
            .collect();
        CubeMap { size, levels }
    }

    /// Two lens objects (two and one layers, every shell kind between them), three viewpoints.
    fn sample_bake(seed: u64, size: u32) -> Bake {
        let mut rng = Pcg64::seed_from_u64(seed);
        let viewpoints = vec![
            Vec3::new(5.0, 1.0, 0.0),
            Vec3::new(4.924_039, 1.0, 0.868_241),
            Vec3::new(4.698_463, 1.0, 1.710_101),
        ];
        let teapot_shells = vec![
            LayerShell::quad_facing(
                DVec3::new(1.5, 0.5, -0.25),
                DVec3::new(-1.0, 0.0, 0.1),
                DVec2::new(0.5, 0.75),
            ),
            LayerShell::Cylinder {
                centre: DVec3::new(0.0, 1.0, 0.0),
                axis: DVec3::Y,
                radius: 3.0,
                half_height: Some(2.0),
            },
            LayerShell::Box {
                centre: DVec3::new(0.0, 2.0, 0.0),
                half_extents: DVec3::new(8.0, 2.5, 6.0),
            },
        ];
        let cup_shells = [
            LayerShell::Sphere {
                centre: DVec3::new(1.5, 0.4, -0.2),
                radius: 1.0 / 3.0,
            },
            LayerShell::Ellipsoid {
                centre: DVec3::new(1.5, 0.4, -0.2),
                radii: DVec3::new(9.0, 3.0, 7.0),
            },
            LayerShell::Cylinder {
                centre: DVec3::ZERO,
                axis: DVec3::new(0.0, 0.6, 0.8),
                radius: 0.1,
                half_height: None,
            },
        ];
        let mut lens = |name: &str, em_origin: DVec3, shells: Vec<LayerShell>| BakedLens {
            name: name.to_owned(),
            em_origins: vec![em_origin; shells.len()],
            maps: (0..viewpoints.len())
                .map(|_| {
                    shells
                        .iter()
                        .map(|_| Arc::new(random_cube(&mut rng, size)))
                        .collect()
                })
                .collect(),
            shells,
            // The mirror's two layers by bounce: the manifest must carry the layering.
            layering: if name == "cup (mirror)" {
                Layering::Bounce
            } else {
                Layering::Distance
            },
        };
        let lenses = vec![
            lens("teapot", DVec3::new(0.0, 0.7, 0.1), teapot_shells),
            lens(
                "cup (mirror)",
                DVec3::new(1.5, 0.4, -0.2),
                cup_shells[..2].to_vec(),
            ),
            lens("rod", DVec3::new(0.1, 0.2, 0.3), cup_shells[2..].to_vec()),
        ];
        Bake {
            scene: "teapot-room".to_owned(),
            created_by: lensmap::layers::bake::default_created_by(),
            viewpoints,
            lenses,
            provenance: None,
        }
    }

    /// Every f32 of every texel of every level, as bits (so −0 ≠ 0 and NaN would show).
    fn bits(bake: &Bake) -> Vec<u32> {
        bake.lenses
            .iter()
            .flat_map(|lens| lens.maps.iter().flatten())
            .flat_map(|cube| cube.levels.iter().flatten().flatten())
            .flat_map(|texel| texel.map(f32::to_bits))
            .collect()
    }

    fn assert_same_bake(read: &Bake, written: &Bake) {
        assert!(bits(read) == bits(written), "texels differ");
        assert_eq!(read.scene, written.scene);
        assert_eq!(read.created_by, written.created_by);
        assert_eq!(read.viewpoints, written.viewpoints);
        for (r, w) in read.lenses.iter().zip(&written.lenses) {
            assert_eq!(
                (&r.name, &r.em_origins, &r.shells),
                (&w.name, &w.em_origins, &w.shells)
            );
        }
        assert!(read == written, "bakes differ");
    }

    /// The file of lens 0, viewpoint `v`, layer `k` of a written bake.
    fn map_path(dir: &Path, v: usize, k: usize) -> PathBuf {
        let at = LensIndex::new(0).layer(LayerIndex::new(k));
        dir.join(map_file_name(at, "teapot", v))
    }

    /// Reads `dir`, expecting a failure whose one-line message mentions every one of `needles`.
    fn read_error(dir: &Path, needles: &[&str]) -> BakeError {
        let error = Bake::read(dir).expect_err("the bake should be rejected");
        let message = error.to_string();
        assert!(!message.contains('\n'), "not one line: {message}");
        for needle in needles {
            assert!(
                message.contains(needle),
                "'{needle}' missing from: {message}"
            );
        }
        error
    }

    /// Replaces the manifest by `edit(manifest)`.
    fn edit_manifest(dir: &Path, edit: impl FnOnce(&mut Manifest)) {
        let mut manifest = Manifest::read(dir).unwrap();
        edit(&mut manifest);
        fs::write(dir.join(MANIFEST_FILE_NAME), manifest.to_json()).unwrap();
    }

    /// Entries of the folder holding the bake directory (to see staging/previous leftovers).
    fn siblings(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir.parent().unwrap())
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    // ------------------------------------------------------------ round trips and atomicity

    #[test]
    fn round_trip_is_bit_exact() {
        let dir = fresh("round-trip");
        let bake = sample_bake(1, 8);
        bake.write(&dir).unwrap();
        let read = Bake::read(&dir).unwrap();
        assert_same_bake(&read, &bake);
        // 3 lenses' layers (3 + 2 + 1) × 3 viewpoints EXRs plus the manifest.
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 6 * 3 + 1);
        let manifest = Manifest::read(&dir).unwrap();
        assert_eq!(manifest.cube_map_size, 8);
        assert_eq!(
            manifest.lenses[1].layers[0].maps[2],
            "lens1-cup__mirror_.v002.layer0.exr"
        );
        assert_eq!(siblings(&dir), ["bake"]);
        // A 1×1 cube map (one level) round-trips too.
        let dir = fresh("round-trip-1x1");
        let tiny = sample_bake(2, 1);
        tiny.write(&dir).unwrap();
        assert_same_bake(&Bake::read(&dir).unwrap(), &tiny);
    }

    /// `sample_bake` whose cup shares the teapot's farthest layer: same shell, the teapot's EM
    /// origin, the very same maps.
    fn shared_bake(seed: u64, size: u32) -> Bake {
        let mut bake = sample_bake(seed, size);
        let (teapot, cup) = (bake.lenses[0].clone(), &mut bake.lenses[1]);
        cup.shells[1] = teapot.shells[2];
        cup.em_origins[1] = teapot.em_origins[2];
        for (cup_maps, teapot_maps) in cup.maps.iter_mut().zip(&teapot.maps) {
            cup_maps[1] = teapot_maps[2].clone();
        }
        bake
    }

    #[test]
    fn a_shared_layer_is_stored_once_and_read_as_one_map() {
        let dir = fresh("shared");
        let bake = shared_bake(31, 4);
        bake.write(&dir).unwrap();
        // 6 layers × 3 viewpoints, less the cup's shared layer's 3 files, plus the manifest.
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 6 * 3 - 3 + 1);
        let manifest = Manifest::read(&dir).unwrap();
        let (teapot, cup) = (&manifest.lenses[0], &manifest.lenses[1]);
        assert_eq!(cup.layers[1].maps, teapot.layers[2].maps);
        assert_eq!(cup.layers[1].em_origin, Some(teapot.em_origin));
        assert_eq!(
            cup.layers[0].em_origin, None,
            "its own origin is the lens's"
        );
        assert_eq!(cup.layer_origin(1), teapot.em_origin);
        let read = Bake::read(&dir).unwrap();
        assert_same_bake(&read, &bake);
        for v in 0..3 {
            assert!(
                Arc::ptr_eq(&read.lenses[1].maps[v][1], &read.lenses[0].maps[v][2]),
                "viewpoint {v}: the shared file is read once, as one map"
            );
        }
        // Equal texels alone do not share: a copy (another Arc) is written as its own file.
        let mut copied = shared_bake(31, 4);
        for maps in &mut copied.lenses[1].maps {
            maps[1] = Arc::new(CubeMap::clone(&maps[1]));
        }
        let dir = fresh("shared-copy");
        copied.write(&dir).unwrap();
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 6 * 3 + 1);
    }

    #[test]
    fn a_file_listed_by_layers_that_do_not_share_it_is_refused() {
        let dir = fresh("shared-mismatch");
        shared_bake(32, 2).write(&dir).unwrap();
        // The cup's layer moves its origin: it would read the teapot's map from elsewhere.
        edit_manifest(&dir, |m| {
            m.lenses[1].layers[1].em_origin = Some(DVec3::ZERO)
        });
        read_error(
            &dir,
            &[
                "lenses[1].layers[1].maps[0]",
                "lens0-teapot.v000.layer2.exr",
                "lenses[0].layers[2].maps[0]",
                "same shell and EM origin",
            ],
        );
        // One map for two viewpoints of one layer (the same shell and origin) is fine, read once;
        // the same file for a layer with another shell is not.
        let dir = fresh("shared-viewpoint");
        sample_bake(33, 2).write(&dir).unwrap();
        edit_manifest(&dir, |m| {
            m.lenses[0].layers[0].maps[1] = m.lenses[0].layers[0].maps[0].clone()
        });
        let read = Bake::read(&dir).unwrap();
        assert!(Arc::ptr_eq(
            &read.lenses[0].maps[0][0],
            &read.lenses[0].maps[1][0]
        ));
        edit_manifest(&dir, |m| {
            m.lenses[0].layers[1].maps[0] = m.lenses[0].layers[0].maps[0].clone()
        });
        read_error(
            &dir,
            &["lenses[0].layers[1].maps[0]", "lenses[0].layers[0].maps[0]"],
        );
        // A layer origin that is not finite.
        let dir = fresh("shared-origin");
        shared_bake(34, 2).write(&dir).unwrap();
        edit_manifest(&dir, |m| {
            m.lenses[1].layers[1].em_origin = Some(DVec3::new(1e300, 0.0, 0.0))
        });
        read_error(
            &dir,
            &["lenses[1].layers[1].em_origin", "bake the scene again"],
        );
    }

    #[test]
    fn an_independent_exr_reader_sees_the_documented_layout() {
        // The `image` crate reads the first part of a file: it must be level 0 of +X, rows top to
        // bottom, RGBA in that order, the premultiplied values untouched.
        let dir = fresh("independent-reader");
        let bake = sample_bake(25, 8);
        bake.write(&dir).unwrap();
        let decoded = image::open(map_path(&dir, 1, 2)).unwrap().into_rgba32f();
        assert_eq!(decoded.dimensions(), (8, 8));
        let expected = &bake.lenses[0].maps[1][2].levels[0][0];
        let found: Vec<[u32; 4]> = decoded.pixels().map(|p| p.0.map(f32::to_bits)).collect();
        let expected: Vec<[u32; 4]> = expected.iter().map(|t| t.map(f32::to_bits)).collect();
        assert_eq!(found, expected);
    }

    #[test]
    fn the_same_bake_writes_the_same_bytes() {
        let (first, second) = (fresh("bytes-a"), fresh("bytes-b"));
        let bake = sample_bake(3, 4);
        bake.write(&first).unwrap();
        bake.write(&second).unwrap();
        let mut files: Vec<_> = fs::read_dir(&first)
            .unwrap()
            .map(|entry| entry.unwrap().file_name())
            .collect();
        files.sort();
        for file in files {
            assert_eq!(
                fs::read(first.join(&file)).unwrap(),
                fs::read(second.join(&file)).unwrap(),
                "{file:?}"
            );
        }
    }

    #[test]
    fn a_new_bake_replaces_the_old_one_and_leaves_nothing_behind() {
        let dir = fresh("replace");
        sample_bake(4, 4).write(&dir).unwrap();
        // Fewer viewpoints and a larger size: no stale file of the old bake may survive.
        let mut newer = sample_bake(5, 8);
        newer.viewpoints.truncate(1);
        for lens in &mut newer.lenses {
            lens.maps.truncate(1);
        }
        newer.write(&dir).unwrap();
        assert_same_bake(&Bake::read(&dir).unwrap(), &newer);
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 6 + 1);
        assert_eq!(siblings(&dir), ["bake"]);
    }

    #[test]
    fn a_failed_write_leaves_the_old_bake_intact() {
        let dir = fresh("failed-write");
        let old = sample_bake(6, 4);
        old.write(&dir).unwrap();
        // The very last map is bad, so the write fails after most files are on disk.
        let mut broken = sample_bake(7, 4);
        let last = broken.lenses.last_mut().unwrap().maps.last_mut().unwrap();
        Arc::make_mut(last.last_mut().unwrap()).levels[1][5][3][2] = f32::NAN;
        let error = broken.write(&dir).expect_err("NaN must be refused");
        let message = error.to_string();
        assert!(matches!(error, BakeError::NonFinite { .. }), "{message}");
        assert!(message.contains("lens2-rod.v002.layer0.exr") && message.contains("level1/-Z"));
        assert!(
            message.contains("(1, 1)") && message.contains("channel B"),
            "{message}"
        );
        assert_same_bake(&Bake::read(&dir).unwrap(), &old);
        assert_eq!(siblings(&dir), ["bake"]);
    }

    /// A reader in a loop while a writer replaces the bake again and again: every read is the
    /// old bake or the new one, whole (never maps of both: the two bakes have the same file
    /// names and different texels), and never "not found". A second writer meanwhile is refused,
    /// naming the first.
    #[test]
    fn a_reader_during_replaces_sees_one_bake_whole() {
        let dir = fresh("reader-during-replaces");
        let bakes = [sample_bake(21, 4), sample_bake(22, 4)];
        let texels = bakes.each_ref().map(bits);
        assert_ne!(texels[0], texels[1]);
        bakes[0].write(&dir).unwrap();
        let replaces = 150;
        let done = std::sync::atomic::AtomicBool::new(false);
        let (reads, seen) = std::thread::scope(|scope| {
            scope.spawn(|| {
                for i in 0..replaces {
                    bakes[(i + 1) % 2].write(&dir).unwrap();
                }
                done.store(true, std::sync::atomic::Ordering::Release);
            });
            let (mut reads, mut seen) = (0, [0usize; 2]);
            while !done.load(std::sync::atomic::Ordering::Acquire) {
                let read = Bake::read(&dir).unwrap_or_else(|e| panic!("read {reads}: {e}"));
                let which = texels
                    .iter()
                    .position(|t| *t == bits(&read))
                    .unwrap_or_else(|| panic!("read {reads} mixes the two bakes"));
                assert!(read == bakes[which]);
                seen[which] += 1;
                reads += 1;
            }
            (reads, seen)
        });
        eprintln!("{reads} reads during {replaces} replaces: {seen:?} of each bake");
        assert!(seen[0] > 0 && seen[1] > 0, "both bakes read: {seen:?}");
        assert_eq!(siblings(&dir), ["bake"]);
    }

    #[test]
    fn a_second_writer_is_refused_while_the_first_holds_the_lock() {
        let dir = fresh("two-writers");
        sample_bake(23, 2).write(&dir).unwrap();
        let held = lensmap::atomic::lock::DirectoryLock::acquire(&dir).unwrap();
        let error = sample_bake(24, 2)
            .write(&dir)
            .expect_err("the lock is held");
        let message = error.to_string();
        assert!(matches!(error, BakeError::Lock(_)), "{message}");
        assert!(
            message.contains(&format!("pid {}", std::process::id()))
                && message.contains(".bake.lock")
                && !message.contains('\n'),
            "{message}"
        );
        assert_same_bake(&Bake::read(&dir).unwrap(), &sample_bake(23, 2));
        drop(held);
        // What a writer killed mid-write leaves (its staging): the next writer removes it.
        let killed = dir.with_file_name(".bake.writing-999999");
        fs::create_dir_all(&killed).unwrap();
        fs::write(killed.join("manifest.json"), b"{}").unwrap();
        sample_bake(24, 2).write(&dir).unwrap();
        assert_same_bake(&Bake::read(&dir).unwrap(), &sample_bake(24, 2));
        assert_eq!(siblings(&dir), ["bake"]);
    }

    #[test]
    fn an_interrupted_swap_is_reported_and_the_next_write_recovers() {
        let dir = fresh("interrupted");
        let old = sample_bake(8, 2);
        old.write(&dir).unwrap();
        // The state a crash between the two renames leaves: the old bake moved aside.
        let previous = dir.with_file_name(".bake.previous");
        fs::rename(&dir, &previous).unwrap();
        let error = read_error(&dir, &[".bake.previous", "rename it back"]);
        assert!(matches!(error, BakeError::InterruptedSwap { .. }));
        // A write whose data is bad still restores the old bake first.
        let mut broken = sample_bake(9, 2);
        Arc::make_mut(&mut broken.lenses[0].maps[0][0]).levels[0][0][0][3] = 2.0;
        assert!(matches!(
            broken.write(&dir),
            Err(BakeError::AlphaOutOfRange { .. })
        ));
        assert_same_bake(&Bake::read(&dir).unwrap(), &old);
        // A crash after the swap leaves both: the next write drops the stale copy.
        fs::create_dir(&previous).unwrap();
        let newer = sample_bake(10, 2);
        newer.write(&dir).unwrap();
        assert_same_bake(&Bake::read(&dir).unwrap(), &newer);
        assert_eq!(siblings(&dir), ["bake"]);
    }

    #[test]
    fn write_refuses_to_replace_a_directory_that_is_not_a_bake() {
        let dir = fresh("not-a-bake");
        fs::create_dir_all(&dir).unwrap();
        fs::write(dir.join("thesis.tex"), "precious").unwrap();
        let error = sample_bake(11, 2).write(&dir).unwrap_err();
        assert!(matches!(error, BakeError::NotABake { .. }), "{error}");
        assert_eq!(
            fs::read_to_string(dir.join("thesis.tex")).unwrap(),
            "precious"
        );
        // An empty directory is fine.
        let empty = fresh("empty-dir");
        fs::create_dir_all(&empty).unwrap();
        sample_bake(11, 2).write(&empty).unwrap();
    }

    #[test]
    fn write_refuses_inconsistent_counts() {
        let dir = fresh("write-counts");
        let mut bake = sample_bake(12, 2);
        bake.lenses[0].maps[1].pop();
        let error = bake.write(&dir).unwrap_err();
        assert!(
            matches!(error, BakeError::InconsistentCount { .. }),
            "{error}"
        );
        assert!(
            error.to_string().contains("lenses[0].maps[1] has 2 layers"),
            "{error}"
        );
        let mut bake = sample_bake(12, 2);
        bake.lenses[1].maps.pop();
        let error = bake.write(&dir).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("lenses[1].maps has 2 viewpoints"),
            "{error}"
        );
        let mut bake = sample_bake(12, 2);
        bake.lenses[2].maps[0][0] = Arc::new(CubeMap::uniform(4, [0.0; 4]));
        let error = bake.write(&dir).unwrap_err();
        assert!(matches!(error, BakeError::WrongSize { .. }), "{error}");
        assert!(!dir.exists());
    }

    // ------------------------------------------------------------ one test per reading error

    #[test]
    fn missing_directory_and_manifest() {
        let dir = fresh("missing-manifest");
        let error = read_error(&dir, &["no such bake directory"]);
        assert!(matches!(error, BakeError::MissingDirectory { .. }));
        fs::create_dir_all(&dir).unwrap();
        let error = read_error(
            &dir,
            &["manifest.json", "not a bake directory", "lensmap bake"],
        );
        assert!(matches!(error, BakeError::MissingManifest { .. }));
    }

    #[test]
    fn malformed_manifest_names_line_and_column() {
        let dir = fresh("malformed");
        sample_bake(13, 2).write(&dir).unwrap();
        let path = dir.join(MANIFEST_FILE_NAME);
        let text = fs::read_to_string(&path).unwrap();
        fs::write(&path, text.replace("\"scene\":", "\"scene\" ")).unwrap();
        let error = read_error(&dir, &["manifest.json:3:", "fix the manifest"]);
        assert!(
            matches!(error, BakeError::ManifestSyntax { line: 3, .. }),
            "{error}"
        );
        // An unknown field is named too.
        fs::write(&path, text.replace("\"scene\":", "\"scene_name\":")).unwrap();
        read_error(&dir, &["manifest.json:3:", "scene_name"]);
    }

    #[test]
    fn wrong_format_version() {
        let dir = fresh("version");
        sample_bake(14, 2).write(&dir).unwrap();
        let path = dir.join(MANIFEST_FILE_NAME);
        let text = fs::read_to_string(&path).unwrap();
        fs::write(
            &path,
            text.replace("\"format_version\": 1", "\"format_version\": 2"),
        )
        .unwrap();
        let error = read_error(
            &dir,
            &["manifest.json", "format_version is 2", "reads version 1"],
        );
        assert!(matches!(error, BakeError::WrongVersion { .. }));
        fs::write(&path, text.replace("\"format_version\": 1,", "")).unwrap();
        read_error(&dir, &["format_version is missing"]);
    }

    #[test]
    fn non_power_of_two_size() {
        let dir = fresh("npot");
        sample_bake(15, 4).write(&dir).unwrap();
        let good = fs::read_to_string(dir.join(MANIFEST_FILE_NAME)).unwrap();
        edit_manifest(&dir, |m| m.cube_map_size = 6);
        let error = read_error(
            &dir,
            &["manifest.json", "cube_map_size is 6", "power-of-two"],
        );
        assert!(matches!(error, BakeError::NonPowerOfTwo { size: 6, .. }));
        fs::write(dir.join(MANIFEST_FILE_NAME), good).unwrap();
        edit_manifest(&dir, |m| m.cube_map_size = 0);
        read_error(&dir, &["cube_map_size is 0"]);
        // In memory: a 6×6 cube map is refused before anything is written.
        let mut bake = sample_bake(15, 4);
        for cube in bake
            .lenses
            .iter_mut()
            .flat_map(|l| l.maps.iter_mut().flatten())
        {
            *cube = Arc::new(CubeMap::uniform(6, [0.0; 4]));
        }
        let error = bake.write(&fresh("npot-write")).unwrap_err();
        assert!(
            matches!(error, BakeError::NonPowerOfTwo { size: 6, .. }),
            "{error}"
        );
    }

    #[test]
    fn inconsistent_layer_map_counts() {
        let dir = fresh("counts");
        sample_bake(16, 2).write(&dir).unwrap();
        edit_manifest(&dir, |m| {
            m.lenses[0].layers[2].maps.pop();
        });
        let error = read_error(
            &dir,
            &["lenses[0].layers[2].maps has 2 files", "viewpoints has 3"],
        );
        assert!(matches!(error, BakeError::InconsistentCount { .. }));
    }

    #[test]
    fn invalid_manifest_fields() {
        let dir = fresh("fields");
        sample_bake(17, 2).write(&dir).unwrap();
        let path = dir.join(MANIFEST_FILE_NAME);
        let good = fs::read_to_string(&path).unwrap();
        type Edit = fn(&mut Manifest);
        let cases: [(&str, Edit); 8] = [
            // Finite but absurd: f32 texture directions would lose all precision.
            ("lenses[0].em_origin", |m| {
                m.lenses[0].em_origin = DVec3::new(1e300, 0.0, 0.0)
            }),
            ("lenses[1].layers[0].shell.radius", |m| {
                m.lenses[1].layers[0].shell = LayerShell::Sphere {
                    centre: DVec3::ZERO,
                    radius: -1.0,
                }
            }),
            ("lenses[0].layers[1].maps[0]", |m| {
                m.lenses[0].layers[1].maps[0] = "../elsewhere.exr".into()
            }),
            ("lenses[0].layers[0].maps[1]", |m| {
                m.lenses[0].layers[0].maps[1] = "/etc/passwd".into()
            }),
            ("lenses[1].name", |m| m.lenses[1].name = "teapot".into()),
            ("lenses[2].layers is empty", |m| m.lenses[2].layers.clear()),
            ("viewpoints is empty", |m| {
                m.viewpoints.clear();
                for lens in &mut m.lenses {
                    for layer in &mut lens.layers {
                        layer.maps.clear();
                    }
                }
            }),
            ("lenses is empty", |m| m.lenses.clear()),
        ];
        for (field, edit) in cases {
            fs::write(&path, &good).unwrap();
            edit_manifest(&dir, edit);
            let error = read_error(&dir, &["manifest.json", field]);
            assert!(matches!(error, BakeError::Invalid { .. }), "{error}");
        }
        // Non-finite numbers cannot even be written as JSON numbers.
        fs::write(&path, good.replacen("5.0,", "1e999,", 1)).unwrap();
        read_error(&dir, &["manifest.json:"]);
    }

    #[test]
    fn missing_exr() {
        let dir = fresh("missing-exr");
        sample_bake(18, 2).write(&dir).unwrap();
        fs::remove_file(map_path(&dir, 1, 2)).unwrap();
        let error = read_error(
            &dir,
            &[
                "lens0-teapot.v001.layer2.exr",
                "lenses[0].layers[2].maps[1]",
                "restore",
            ],
        );
        assert!(matches!(error, BakeError::MissingMap { .. }));
    }

    #[test]
    fn unreadable_exr() {
        let dir = fresh("garbage-exr");
        sample_bake(19, 2).write(&dir).unwrap();
        fs::write(map_path(&dir, 0, 0), b"not an EXR file at all").unwrap();
        let error = read_error(&dir, &["lens0-teapot.v000.layer0.exr", "OpenEXR"]);
        assert!(matches!(error, BakeError::Exr { .. }));
    }

    #[test]
    fn wrong_size_exr() {
        let dir = fresh("wrong-size");
        sample_bake(20, 8).write(&dir).unwrap();
        let mut rng = Pcg64::seed_from_u64(20);
        write_cube_map_exr(&random_cube(&mut rng, 4), &map_path(&dir, 2, 1)).unwrap();
        let error = read_error(
            &dir,
            &[
                "lens0-teapot.v002.layer1.exr",
                "level0/+X",
                "4×4",
                "expected 8×8",
            ],
        );
        assert!(matches!(error, BakeError::WrongSize { .. }));
    }

    #[test]
    fn missing_mip_level() {
        let dir = fresh("missing-level");
        sample_bake(21, 8).write(&dir).unwrap();
        let mut rng = Pcg64::seed_from_u64(21);
        let mut cube = random_cube(&mut rng, 8);
        cube.levels.pop();
        write_cube_map_exr(&cube, &map_path(&dir, 0, 1)).unwrap();
        let error = read_error(
            &dir,
            &[
                "lens0-teapot.v000.layer1.exr",
                "level3/+X",
                "all 4 mip levels",
            ],
        );
        assert!(matches!(error, BakeError::MissingLevel { .. }));
        // An extra level is an unexpected part.
        let mut cube = random_cube(&mut rng, 8);
        let extra = cube.levels[3].clone();
        cube.levels.push(extra);
        write_cube_map_exr(&cube, &map_path(&dir, 0, 1)).unwrap();
        let error = read_error(&dir, &["level4/+X", "is not one of"]);
        assert!(matches!(error, BakeError::BadPart { .. }));
    }

    #[test]
    fn non_finite_texels() {
        for (value, shown) in [
            (f32::NAN, "NaN"),
            (f32::INFINITY, "inf"),
            (f32::NEG_INFINITY, "-inf"),
        ] {
            let dir = fresh("non-finite");
            sample_bake(22, 4).write(&dir).unwrap();
            let mut rng = Pcg64::seed_from_u64(22);
            let mut cube = random_cube(&mut rng, 4);
            cube.levels[0][3][2 * 4 + 1][0] = value;
            write_cube_map_exr(&cube, &map_path(&dir, 1, 0)).unwrap();
            let error = read_error(
                &dir,
                &[
                    "lens0-teapot.v001.layer0.exr",
                    "level0/-Y",
                    "texel (1, 2) channel R",
                    shown,
                    "finite",
                ],
            );
            assert!(matches!(error, BakeError::NonFinite { .. }));
        }
    }

    #[test]
    fn alpha_out_of_range() {
        for alpha in [-1e-3f32, 1.0 + 1e-3, 7.0] {
            let dir = fresh("alpha");
            sample_bake(23, 4).write(&dir).unwrap();
            let mut rng = Pcg64::seed_from_u64(23);
            let mut cube = random_cube(&mut rng, 4);
            cube.levels[2][4][0][3] = alpha;
            write_cube_map_exr(&cube, &map_path(&dir, 0, 2)).unwrap();
            let error = read_error(
                &dir,
                &[
                    "lens0-teapot.v000.layer2.exr",
                    "level2/+Z",
                    "texel (0, 0)",
                    "clamp",
                ],
            );
            assert!(
                matches!(error, BakeError::AlphaOutOfRange { .. }),
                "{error}"
            );
        }
        // Within the tolerance: accepted as stored.
        let mut rng = Pcg64::seed_from_u64(24);
        let mut cube = random_cube(&mut rng, 2);
        cube.levels[0][0][0][3] = 1.0 + ALPHA_TOLERANCE / 2.0;
        cube.levels[0][0][1][3] = -ALPHA_TOLERANCE / 2.0;
        let path = fresh("alpha-tolerance").with_extension("exr");
        write_cube_map_exr(&cube, &path).unwrap();
        assert_eq!(read_cube_map_exr(&path, 2).unwrap(), cube);
    }
}
