//! Bad scene input: every case must fail with one line naming the file, the field and a fix, and
//! never panic. Bad assets (OBJ, EXR, PNG) are written into a fresh temporary folder per test.

/// Named `scene_errors` so that `cargo test -p lensmap-tests scene` selects these tests.
mod scene_errors {
    use std::path::{Path, PathBuf};

    use lensmap::scene::{Scene, SceneError};
    use lensmap_tests::fixtures::{SMALL_SCENE, edit_scene, temp_dir};

    /// What [`SMALL_SCENE`] needs to be these tests' valid scene: a circle of four viewpoint
    /// samples and a lens object (the ball).
    const VIEWS_AND_LENS: &str = r#"
[view_space.circle]
centre = [0, 1, 0]
radius = 5
height = 0.5
step_degrees = 8
count = 4

[[lenses]]
name = "lens"
objects = ["ball"]
"#;

    /// A valid scene; each test breaks one thing in it.
    fn base() -> String {
        format!("{SMALL_SCENE}{VIEWS_AND_LENS}")
    }

    /// A fresh, empty folder for one test.
    fn temp_folder(test: &str) -> PathBuf {
        temp_dir("scene-errors", test)
    }

    /// Writes `text` as `scene.toml` into the test's folder and loads it, expecting an error.
    fn load_error(dir: &Path, text: &str) -> (PathBuf, SceneError) {
        let path = dir.join("scene.toml");
        std::fs::write(&path, text).expect("write the scene");
        match Scene::load(&path) {
            Ok(_) => panic!("the scene loaded, but it should not have:\n{text}"),
            Err(e) => (path, e),
        }
    }

    /// The base scene with `from` replaced by `to` (which must occur).
    fn edit(from: &str, to: &str) -> String {
        edit_scene(&base(), from, to)
    }

    /// The message is one line, starts with the file, names the field, says what is wrong (`what`)
    /// and offers a fix (`fix`), separated by "; ".
    fn assert_message(error: &SceneError, file: &Path, field: &str, what: &str, fix: &str) {
        let message = error.to_string();
        assert!(!message.contains('\n'), "not one line: {message}");
        assert!(
            message.starts_with(&file.display().to_string()),
            "does not start with the file {}: {message}",
            file.display()
        );
        assert!(
            message.contains(&format!(": {field}")),
            "does not name {field}: {message}"
        );
        assert_eq!(error.field(), field, "{message}");
        assert!(message.contains(what), "does not say {what:?}: {message}");
        assert!(
            error.fix().contains(fix),
            "fix does not say {fix:?}: {message}"
        );
        assert!(
            message.ends_with(&format!("; {}", error.fix())),
            "{message}"
        );
    }

    /// An edit of the base scene: `.0` replaced by `.1`.
    struct Edit<'a>(&'a str, &'a str);

    /// The base scene with `from` replaced by `to`, loaded from `dir`: refused with one line
    /// naming the file and `field`, saying `what` and offering `fix` ([`assert_message`]). The
    /// error, for further checks.
    fn assert_refused(
        dir: &Path,
        Edit(from, to): Edit<'_>,
        field: &str,
        what: &str,
        fix: &str,
    ) -> SceneError {
        let (file, error) = load_error(dir, &edit(from, to));
        assert_message(&error, &file, field, what, fix);
        error
    }

    /// An object of the wrong kind in a lens is refused naming its material's kind: diffuse or
    /// glossy (a glossy object was once called diffuse).
    #[test]
    fn a_lens_member_that_is_neither_glass_nor_mirror_is_named_by_its_kind() {
        let dir = temp_folder("lens-member-kind");
        let lens = "objects = [\"ball\"]";
        assert_refused(
            &dir,
            Edit(lens, "objects = [\"floor\"]"),
            "lenses[0].objects[0]",
            "object \"floor\" is diffuse, but a lens is made of glass or mirror objects",
            "give the object a glass or mirror material",
        );
        let glossy = edit_scene(
            &edit(lens, "objects = [\"floor\"]"),
            "diffuse = { colour = [0.5, 0.5, 0.5] }",
            "glossy = { diffuse = [0.5, 0.5, 0.5], specular = [0.5, 0.5, 0.5], exponent = 100 }",
        );
        let (file, error) = load_error(&dir, &glossy);
        assert_message(
            &error,
            &file,
            "lenses[0].objects[0]",
            "object \"floor\" is glossy, but a lens is made of glass or mirror objects",
            "give the object a glass or mirror material",
        );
    }

    /// `terms` as a count on a lens of glass and mirrors is refused naming the field (whose
    /// first classes would they be?); a list there loads, and a count on glass alone does.
    #[test]
    fn a_count_of_path_classes_needs_a_lens_of_one_kind() {
        let dir = temp_folder("terms-kind");
        let with_mirror = edit_scene(
            &base(),
            "[[objects]]\nname = \"ball\"",
            "[[materials]]\nname = \"chrome\"\nmirror = { reflectance = [0.9, 0.9, 0.9] }\n\n[[objects]]\nname = \"bead\"\nmaterial = \"chrome\"\nsphere = { radius = 0.2, segments = 8, rings = 4 }\ntransform = { translate = [2, 1, 0] }\n\n[[objects]]\nname = \"ball\"",
        );
        let lens = "objects = [\"ball\"]";
        let mixed = |terms: &str| {
            edit_scene(
                &with_mirror,
                lens,
                &format!("objects = [\"ball\", \"bead\"]\nterms = {terms}"),
            )
        };
        let (file, error) = load_error(&dir, &mixed("4"));
        assert_message(
            &error,
            &file,
            "lenses[0].terms",
            "joins glass and mirrors",
            "list the classes",
        );
        for loads in [
            mixed("[\"R\", \"TT\", \"RR\"]"),
            edit(lens, "objects = [\"ball\"]\nterms = 4"),
        ] {
            let path = dir.join("loads.toml");
            std::fs::write(&path, &loads).expect("write the scene");
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(scene.lenses[0].terms.is_some());
        }
    }

    /// A valid scene that loads; guards against the tests failing for the wrong reason.
    #[test]
    fn the_base_scene_loads() {
        let dir = temp_folder("base");
        let path = dir.join("scene.toml");
        std::fs::write(&path, base()).expect("write the scene");
        match Scene::load(&path) {
            Ok(scene) => assert_eq!(scene.view_space.len(), 4),
            Err(e) => panic!("{e}"),
        }
    }

    /// `layering`: a word it does not know, "bounce" on a glass lens, or beside `layers`; a
    /// mirror lens by bounce loads, and says so.
    #[test]
    fn layering_by_bounce_is_for_mirrors_without_layers() {
        let dir = temp_folder("layering");
        let lens = "objects = [\"ball\"]";
        assert_refused(
            &dir,
            Edit(lens, "objects = [\"ball\"]\nlayering = \"sideways\""),
            "lenses[0].layering",
            "\"sideways\" is not a layering",
            "\"bounce\"",
        );
        assert_refused(
            &dir,
            Edit(lens, "objects = [\"ball\"]\nlayering = \"bounce\""),
            "lenses[0].layering",
            "object \"ball\" is glass",
            "leave layering out",
        );
        let mirror = edit_scene(
            &base(),
            "glass = { ior = 1.5, absorption = [0.9, 0.9, 0.9] }",
            "mirror = { reflectance = [0.9, 0.9, 0.9] }",
        );
        let with_layers = edit_scene(
            &mirror,
            lens,
            "objects = [\"ball\"]\nlayering = \"bounce\"\nlayers = [{ sphere = 3.0 }]",
        );
        let (file, error) = load_error(&dir, &with_layers);
        assert_message(
            &error,
            &file,
            "lenses[0].layering",
            "also lists layers",
            "remove either",
        );
        let path = dir.join("mirror.toml");
        std::fs::write(
            &path,
            edit_scene(&mirror, lens, "objects = [\"ball\"]\nlayering = \"bounce\""),
        )
        .unwrap();
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.lenses[0].layering, lensmap::layers::Layering::Bounce);
        let plain = dir.join("plain.toml");
        std::fs::write(&plain, &mirror).unwrap();
        let scene = Scene::load(&plain).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            scene.lenses[0].layering,
            lensmap::layers::Layering::Distance
        );
    }

    #[test]
    fn malformed_toml_names_line_and_column() {
        let dir = temp_folder("malformed");
        let (file, error) = load_error(&dir, &edit("width = 16", "width = = 16"));
        assert!(
            matches!(error, SceneError::Toml { line: 8, .. }),
            "{error:?}"
        );
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("{}:8:", file.display())),
            "{message}"
        );
        assert!(message.contains("camera.width"), "{message}");
        assert!(message.contains("correct the TOML"), "{message}");
    }

    #[test]
    fn unknown_field_is_named() {
        let dir = temp_folder("unknown");
        let (file, error) = load_error(
            &dir,
            &edit("sphere = { radius = 1,", "spheer = { radius = 1,"),
        );
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("{}:", file.display())),
            "{message}"
        );
        assert_eq!(error.field(), "objects[0].spheer", "{message}");
        assert!(message.contains("unknown field `spheer`"), "{message}");
        assert!(
            error
                .fix()
                .contains("remove the field or correct its spelling"),
            "{message}"
        );

        let (_, error) = load_error(
            &dir,
            &edit("vfov_degrees = 45", "vfov_degrees = 45\nfov = 3"),
        );
        assert_eq!(error.field(), "camera.fov", "{error}");
    }

    #[test]
    fn wrong_type_and_missing_field() {
        let dir = temp_folder("types");
        let (_, error) = load_error(&dir, &edit("width = 16", "width = \"wide\""));
        assert_eq!(error.field(), "camera.width", "{error}");
        assert!(error.to_string().contains("invalid type"), "{error}");
        let (_, error) = load_error(&dir, &edit("vfov_degrees = 45\n", ""));
        assert!(
            error.to_string().contains("missing field `vfov_degrees`"),
            "{error}"
        );
        assert!(error.fix().contains("add the field"), "{error}");
        // Inside inline tables the path goes down to the offending key.
        let (_, error) = load_error(
            &dir,
            &edit(
                "plane = { size = [4, 4] }",
                "plane = { size = [4, 4] }\ntransform = { scale = \"big\" }",
            ),
        );
        assert_eq!(error.field(), "objects[1].transform.scale", "{error}");
        assert!(
            error
                .to_string()
                .contains("expected a number or an array of three numbers"),
            "{error}"
        );
        let (_, error) = load_error(
            &dir,
            &edit("segments = 16,", "segments = 16, segmentz = 3,"),
        );
        assert_eq!(error.field(), "objects[0].sphere.segmentz", "{error}");
    }

    #[test]
    fn missing_obj_names_the_resolved_path() {
        let dir = temp_folder("missing-obj");
        let error = assert_refused(
            &dir,
            Edit(
                "plane = { size = [4, 4] }",
                "obj = { path = \"meshes/floor.obj\" }",
            ),
            "objects[1].obj.path",
            "cannot read",
            "check the path",
        );
        assert!(
            error
                .to_string()
                .contains(&dir.join("meshes/floor.obj").display().to_string())
        );
    }

    #[test]
    fn obj_with_nan_vertex() {
        let dir = temp_folder("nan-obj");
        std::fs::write(
            dir.join("bad.obj"),
            "v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
        )
        .expect("write the OBJ");
        let error = assert_refused(
            &dir,
            Edit("plane = { size = [4, 4] }", "obj = { path = \"bad.obj\" }"),
            "objects[1].obj.path",
            "line 3 (`v nan 1 0`): `nan` is not a finite number",
            "Wavefront OBJ",
        );
        assert!(error.to_string().contains("bad.obj"), "{error}");
    }

    #[test]
    fn obj_with_infinite_vertex() {
        let dir = temp_folder("inf-obj");
        std::fs::write(
            dir.join("bad.obj"),
            "v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .expect("write the OBJ");
        assert_refused(
            &dir,
            Edit("plane = { size = [4, 4] }", "obj = { path = \"bad.obj\" }"),
            "objects[1].obj.path",
            "line 2 (`v inf 0 0`): `inf` is not a finite number",
            "Wavefront OBJ",
        );
    }

    #[test]
    fn obj_with_degenerate_triangles_is_rejected_or_dropped_on_request() {
        let dir = temp_folder("degenerate-obj");
        // Triangle 1 repeats a vertex, triangle 2 is collinear; triangles 0 and 3 are fine.
        let obj =
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 2\nf 1 2 5\nf 1 3 4\n";
        std::fs::write(dir.join("flat.obj"), obj).expect("write the OBJ");
        assert_refused(
            &dir,
            Edit("plane = { size = [4, 4] }", "obj = { path = \"flat.obj\" }"),
            "objects[1].obj.path",
            "2 degenerate (zero-area) triangle(s), the first is triangle 1 (0-based) (a face on line 7)",
            "drop_degenerate = true",
        );

        let fixed = edit(
            "plane = { size = [4, 4] }",
            "obj = { path = \"flat.obj\", drop_degenerate = true }",
        );
        let path = dir.join("fixed.toml");
        std::fs::write(&path, fixed).expect("write the scene");
        match Scene::load(&path) {
            Ok(scene) => {
                let mesh = &scene.objects[1].mesh;
                assert_eq!(mesh.triangle_count(), 2);
                // No normals in the file: generated, unit, facing +z like the triangles.
                for &i in mesh.triangles.iter().flatten() {
                    assert!((mesh.normals[i as usize].z - 1.0).abs() < 1e-6);
                }
            }
            Err(e) => panic!("{e}"),
        }
    }

    /// Writes a 4×2 RGB float EXR whose texel (1, 0) is `bad`.
    fn write_exr(path: &Path, bad: f32) {
        let mut pixels = vec![0.5f32; 4 * 2 * 3];
        pixels[3] = bad;
        let image = image::Rgb32FImage::from_raw(4, 2, pixels).expect("image buffer");
        image.save(path).expect("write the EXR");
    }

    #[test]
    fn environment_exr_with_nan() {
        let dir = temp_folder("nan-exr");
        write_exr(&dir.join("sky.exr"), f32::NAN);
        let error = assert_refused(
            &dir,
            Edit(
                "constant = [0.1, 0.1, 0.1]",
                "latlong = { path = \"sky.exr\" }",
            ),
            "environment.latlong.path",
            "NaN, infinite or negative",
            "finite, non-negative radiance",
        );
        assert!(error.to_string().contains("pixel (1, 0)"), "{error}");
    }

    #[test]
    fn texture_exr_with_infinity_and_a_good_one() {
        let dir = temp_folder("inf-texture");
        write_exr(&dir.join("wood.exr"), f32::INFINITY);
        assert_refused(
            &dir,
            Edit(
                "diffuse = { colour = [0.5, 0.5, 0.5] }",
                "diffuse = { image = \"wood.exr\" }",
            ),
            "materials[1].diffuse.image",
            "NaN, infinite or negative",
            "non-negative texels",
        );

        write_exr(&dir.join("good.exr"), 0.25);
        let path = dir.join("good.toml");
        std::fs::write(
            &path,
            edit(
                "diffuse = { colour = [0.5, 0.5, 0.5] }",
                "diffuse = { image = \"good.exr\" }",
            ),
        )
        .expect("write the scene");
        match Scene::load(&path) {
            Ok(scene) => match &scene.materials[1] {
                lensmap::scene::Material::Diffuse {
                    texture: Some(lensmap::scene::Texture::Image(t)),
                    ..
                } => {
                    assert_eq!((t.width, t.height), (4, 2));
                    assert_eq!(t.texels[1].x, 0.25);
                }
                other => panic!("{other:?}"),
            },
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn unreadable_image_is_named() {
        let dir = temp_folder("bad-png");
        std::fs::write(dir.join("wood.png"), b"not a png").expect("write junk");
        assert_refused(
            &dir,
            Edit(
                "diffuse = { colour = [0.5, 0.5, 0.5] }",
                "diffuse = { image = \"wood.png\" }",
            ),
            "materials[1].diffuse.image",
            "cannot read the image",
            "readable PNG or EXR",
        );
    }

    #[test]
    fn ior_must_be_positive() {
        let dir = temp_folder("ior");
        for bad in ["0", "-1.5", "nan"] {
            assert_refused(
                &dir,
                Edit("ior = 1.5", &format!("ior = {bad}")),
                "materials[0].glass.ior",
                "is not > 0",
                "index of refraction, e.g. 1.5",
            );
        }
    }

    #[test]
    fn absorption_must_be_in_zero_one() {
        let dir = temp_folder("absorption");
        for bad in ["[0.0, 0.9, 0.9]", "[0.9, 1.5, 0.9]", "[0.9, 0.9, -0.1]"] {
            assert_refused(
                &dir,
                Edit(
                    "absorption = [0.9, 0.9, 0.9]",
                    &format!("absorption = {bad}"),
                ),
                "materials[0].glass.absorption",
                "outside (0, 1]",
                "(0, 1] (1 = clear glass)",
            );
        }
    }

    #[test]
    fn glossy_values_are_checked() {
        let dir = temp_folder("glossy");
        let grey = "diffuse = { colour = [0.5, 0.5, 0.5] }";
        let field = "materials[1].glossy";
        let cases: [(&str, &str, &str, &str); 5] = [
            (
                "glossy = { diffuse = [0.6, 0.6, 0.6], specular = [0.5, 0.3, 0.3], exponent = 10 }",
                field,
                "above 1 in a channel",
                "at most 1 per channel",
            ),
            (
                "glossy = { specular = [0.5, 0.5, 0.5] }",
                field,
                "has a specular lobe but no exponent",
                "add exponent = N",
            ),
            (
                "glossy = { specular = [0.5, 0.5, 0.5], exponent = 0.5 }",
                "materials[1].glossy.exponent",
                "outside [1, 100000]",
                "Phong exponent",
            ),
            (
                "glossy = { diffuse = [0.5, 0.5, 0.5], coat = { ior = 1.0, exponent = 100 } }",
                "materials[1].glossy.coat.ior",
                "outside (1, 3]",
                "clear coat's index of refraction",
            ),
            (
                "glossy = { diffuse = [0.5, 0.5, 0.5] }\ndiffuse = { colour = [0.5, 0.5, 0.5] }",
                "materials[1]",
                "needs exactly one of glass, mirror, diffuse or glossy",
                "keep one of",
            ),
        ];
        for (bad, field, what, fix) in cases {
            assert_refused(&dir, Edit(grey, bad), field, what, fix);
        }
        // A coated Phong material loads.
        let good = edit(
            grey,
            "glossy = { diffuse = [0.3, 0.1, 0.1], specular = [0.2, 0.2, 0.2], exponent = 50, coat = { ior = 1.5, exponent = 900 } }",
        );
        let path = dir.join("good.toml");
        std::fs::write(&path, good).expect("write the scene");
        Scene::load(&path).expect("a glossy material loads");
    }

    /// `environment.studio`: its width in range, not beside another environment; a studio
    /// loads as a lat-long map half as tall as wide, its softboxes the brightest texels.
    #[test]
    fn the_studio_environment_is_checked() {
        let dir = temp_folder("studio");
        let constant = "constant = [0.1, 0.1, 0.1]";
        assert_refused(
            &dir,
            Edit(constant, "studio = { width = 4 }"),
            "environment.studio.width",
            "4 texels is out of range",
            "[8, 8192]",
        );
        assert_refused(
            &dir,
            Edit(constant, "studio = { scale = -1.0 }"),
            "environment.studio.scale",
            "not a finite number ≥ 0",
            "multiplier",
        );
        assert_refused(
            &dir,
            Edit(constant, "studio = {}\nconstant = [0.1, 0.1, 0.1]"),
            "environment",
            "names studio and another environment",
            "keep one of constant, latlong and studio",
        );
        let path = dir.join("studio.toml");
        std::fs::write(&path, edit(constant, "studio = { width = 64 }")).expect("write");
        let scene = Scene::load(&path).expect("a studio loads");
        let lensmap::scene::Environment::LatLong(map) = &scene.environment else {
            panic!("a studio is a lat-long map");
        };
        assert_eq!((map.width, map.height), (64, 32));
        let brightest = map
            .texels
            .iter()
            .map(|t| t.max_element())
            .fold(0.0, f32::max);
        assert_eq!(brightest, 6.0);
    }

    #[test]
    fn camera_look_at_equal_to_position() {
        let dir = temp_folder("look-at");
        assert_refused(
            &dir,
            Edit("look_at = [0, 1, 0]", "look_at = [0, 1, 5]"),
            "camera.look_at",
            "equals look_at",
            "so that they differ",
        );
    }

    #[test]
    fn camera_up_parallel_to_the_view() {
        let dir = temp_folder("up");
        assert_refused(
            &dir,
            Edit("vfov_degrees = 45", "vfov_degrees = 45\nup = [0, 0, -2]"),
            "camera.up",
            "parallel to the view direction",
            "not along look_at − position",
        );
    }

    #[test]
    fn zero_resolution_and_supersampling() {
        let dir = temp_folder("resolution");
        assert_refused(
            &dir,
            Edit("height = 12", "height = 0"),
            "camera.height",
            "resolution is zero",
            "at least 1 pixel",
        );
        assert_refused(
            &dir,
            Edit("supersampling = 1", "supersampling = 0"),
            "camera.supersampling",
            "k = 0",
            "k ≥ 1",
        );
    }

    #[test]
    fn lens_naming_a_missing_object() {
        let dir = temp_folder("lens-missing");
        assert_refused(
            &dir,
            Edit("objects = [\"ball\"]", "objects = [\"bal\"]"),
            "lenses[0].objects[0]",
            "no object is named \"bal\"",
            "ball, floor",
        );
    }

    #[test]
    fn lens_made_of_a_diffuse_object() {
        let dir = temp_folder("lens-diffuse");
        assert_refused(
            &dir,
            Edit("objects = [\"ball\"]", "objects = [\"ball\", \"floor\"]"),
            "lenses[0].objects[1]",
            "\"floor\" is diffuse",
            "glass or mirror material",
        );
    }

    #[test]
    fn view_space_with_no_samples() {
        let dir = temp_folder("view-count");
        assert_refused(
            &dir,
            Edit("count = 4", "count = 0"),
            "view_space.circle.count",
            "0 viewpoint samples",
            "count ≥ 1",
        );
    }

    /// One number must not exhaust memory: sizes past the documented limits are refused at load,
    /// before anything is built, naming the field.
    #[test]
    fn sizes_past_the_limits_are_refused_before_building() {
        let dir = temp_folder("limits");
        let cases = [
            (
                ("count = 4", "count = 4000000000"),
                "view_space.circle.count",
                "4000000000 viewpoint samples",
                "fewer samples",
            ),
            (
                (
                    "plane = { size = [4, 4] }",
                    "plane = { size = [4, 4], subdivisions = 4096 }",
                ),
                "objects[1].plane.subdivisions",
                "33554432 triangles",
                "fewer subdivisions",
            ),
            (
                ("segments = 16, rings = 8", "segments = 4096, rings = 4096"),
                "objects[0].sphere.segments",
                "33554432 triangles",
                "fewer subdivisions",
            ),
        ];
        for ((from, to), field, what, fix) in cases {
            let start = std::time::Instant::now();
            assert_refused(&dir, Edit(from, to), field, what, fix);
            assert!(
                start.elapsed().as_secs_f64() < 5.0,
                "{field}: {:?}",
                start.elapsed()
            );
        }
    }

    /// The circle of [`VIEWS_AND_LENS`], to be replaced by another view space.
    const CIRCLE: &str = "[view_space.circle]\ncentre = [0, 1, 0]\nradius = 5\nheight = 0.5\nstep_degrees = 8\ncount = 4";

    /// A 3 × 3 patch about the look-at point, with `changes` (key = value lines) replacing its
    /// lines of the same key.
    fn patch(changes: &[&str]) -> String {
        let mut lines = vec![
            "radius = 5",
            "azimuth_degrees = [-10, 10]",
            "azimuth_count = 3",
            "elevation_degrees = [0, 20]",
            "elevation_count = 3",
        ];
        for change in changes {
            let key = change.split(" =").next().unwrap_or_default();
            lines.retain(|l| !l.starts_with(&format!("{key} =")));
            lines.push(change);
        }
        format!("[view_space.patch]\n{}", lines.join("\n"))
    }

    #[test]
    fn two_dimensional_view_spaces_load() {
        let dir = temp_folder("view-2d");
        let path = dir.join("scene.toml");
        let cap = "[view_space.cap]\nradius = 5\nhalf_angle_degrees = 30\ncount = 12";
        let list = "[view_space]\nlist = [[0, 1, 5], [1, 1, 5], [0, 2, 5], [1, 2, 4.5]]";
        for (view_space, count) in [(patch(&[]), 9), (cap.to_owned(), 12), (list.to_owned(), 4)] {
            std::fs::write(&path, edit(CIRCLE, &view_space)).expect("write the scene");
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(scene.view_space.len(), count, "{view_space}");
            assert!(scene.view_space.is_surface());
            // Every sample at the radius from the centre (the look-at point by default).
            if !view_space.contains("list") {
                for p in scene.view_space.samples() {
                    assert!((p.distance(scene.camera.look_at) - 5.0).abs() < 1e-4, "{p}");
                }
            }
        }
        // The patch's sample 0 is at its first azimuth and elevation; row-major.
        std::fs::write(&path, edit(CIRCLE, &patch(&[]))).expect("write the scene");
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let samples = scene.view_space.samples();
        let (a, e) = (-10f32.to_radians(), 0f32);
        let want = scene.camera.look_at
            + 5.0 * glam::Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos());
        assert!(samples[0].distance(want) < 1e-5, "{}", samples[0]);
        assert!(samples[1].x.abs() < 1e-5 && samples[3].y > samples[0].y);
    }

    /// Degenerate 2D view spaces are refused in one line naming the field: an empty patch, one
    /// row, a span past the circle, elevations past the poles, samples sharing a direction (a
    /// patch's row on the pole, a list's two samples on one ray from the look-at point), a cap
    /// over 180° or of fewer than three samples, two kinds of view space at once.
    #[test]
    fn degenerate_two_dimensional_view_spaces_are_refused() {
        let dir = temp_folder("view-2d-bad");
        let cap = |changes: &str| format!("[view_space.cap]\nradius = 5\n{changes}");
        let cases = [
            (
                patch(&["azimuth_degrees = [10, 10]"]),
                "view_space.patch.azimuth_degrees",
                "is empty",
                "first < last",
            ),
            (
                patch(&["elevation_count = 1"]),
                "view_space.patch.elevation_count",
                "at least 2 × 2",
                "[view_space.circle]",
            ),
            (
                patch(&["azimuth_count = 0"]),
                "view_space.patch.azimuth_count",
                "at least 2 × 2",
                "count ≥ 2",
            ),
            (
                patch(&["azimuth_degrees = [0, 400]"]),
                "view_space.patch.azimuth_degrees",
                "more than the circle",
                "at most 360°",
            ),
            (
                patch(&["elevation_degrees = [0, 95]"]),
                "view_space.patch.elevation_degrees",
                "leaves [−90, 90]",
                "[-90, 90]",
            ),
            (
                patch(&["elevation_degrees = [0, 90]"]),
                "view_space",
                "samples 6 and 7 lie in the same direction",
                "distinct samples",
            ),
            (patch(&["radius = 0"]), "view_space.patch.radius", "", ""),
            (
                cap("half_angle_degrees = 190\ncount = 12"),
                "view_space.cap.half_angle_degrees",
                "190°",
                "(0, 180]",
            ),
            (
                cap("half_angle_degrees = 30\ncount = 2"),
                "view_space.cap.count",
                "2 sample(s)",
                "count ≥ 3",
            ),
            (
                "[view_space]\nlist = [[0, 1, 5], [0, 1, 10], [1, 1, 5]]".to_owned(),
                "view_space",
                "samples 0 and 1 lie in the same direction",
                "distinct samples",
            ),
            (
                format!("[view_space]\nlist = [[0, 1, 5]]\n{}", patch(&[])),
                "view_space",
                "exactly one of circle, list, patch or cap",
                "[view_space.patch]",
            ),
        ];
        for (view_space, field, what, fix) in cases {
            let (file, error) = load_error(&dir, &edit(CIRCLE, &view_space));
            assert_message(&error, &file, field, what, fix);
        }
    }

    #[test]
    fn a_scene_extends_a_built_in_one() {
        let dir = temp_folder("extends");
        let path = dir.join("room-patch.toml");
        std::fs::write(
            &path,
            format!("extends = \"teapot-room\"\n\n{}", patch(&["radius = 2.8"])),
        )
        .expect("write the scene");
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let room = Scene::load_named("teapot-room").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.name, "room-patch");
        assert_eq!(scene.view_space.len(), 9);
        assert_eq!(
            (scene.objects.len(), scene.lenses.len()),
            (room.objects.len(), room.lenses.len())
        );
        assert_eq!(scene.camera, room.camera);
        assert_ne!(scene.content_hash(), room.content_hash());
        let (file, error) = load_error(&dir, "extends = \"teapot-rooom\"\n");
        assert_message(
            &error,
            &file,
            "extends",
            "not a built-in scene",
            "teapot-room",
        );
    }

    #[test]
    fn view_sample_at_the_look_at_point() {
        let dir = temp_folder("view-list");
        let text = edit(
            "[view_space.circle]\ncentre = [0, 1, 0]\nradius = 5\nheight = 0.5\nstep_degrees = 8\ncount = 4",
            "[view_space]\nlist = [[0, 1, 5], [0, 1, 0]]",
        );
        let (file, error) = load_error(&dir, &text);
        assert_message(
            &error,
            &file,
            "view_space sample 1",
            "equals look_at",
            "so that they differ",
        );
    }

    #[test]
    fn material_and_mesh_references() {
        let dir = temp_folder("references");
        assert_refused(
            &dir,
            Edit("material = \"grey\"", "material = \"gray\""),
            "objects[1].material",
            "no material is named \"gray\"",
            "glass, grey",
        );
        assert_refused(
            &dir,
            Edit(
                "plane = { size = [4, 4] }",
                "plane = { size = [4, 4] }\nbox = { size = [1, 1, 1] }",
            ),
            "objects[1]",
            "exactly one mesh",
            "keep one of obj, plane, box",
        );
        assert_refused(
            &dir,
            Edit("radius = 1,", "radius = -1,"),
            "objects[0].sphere.radius",
            "not a positive number",
            "> 0 (metres)",
        );
        assert_refused(
            &dir,
            Edit(
                "plane = { size = [4, 4] }",
                "plane = { size = [4, 4] }\ntransform = { scale = [1, 0, 1] }",
            ),
            "objects[1].transform.scale",
            "zero or non-finite",
            "non-zero finite",
        );
    }

    #[test]
    fn scene_file_that_does_not_exist() {
        let dir = temp_folder("no-file");
        let path = dir.join("nothing.toml");
        let error = match Scene::load(&path) {
            Ok(_) => panic!("loaded a missing file"),
            Err(e) => e,
        };
        assert_message(
            &error,
            &path,
            "file",
            "cannot read the scene file",
            "teapot-room",
        );
        let error = match Scene::load_named("teapot-rom") {
            Ok(_) => panic!("loaded a misspelt name"),
            Err(e) => e,
        };
        assert_message(
            &error,
            Path::new("teapot-rom"),
            "file",
            "not a built-in scene",
            "teapot-room, glass-sphere, mirror-teapot",
        );
    }
}
