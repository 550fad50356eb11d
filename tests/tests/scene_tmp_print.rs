//! temporary
#[test]
fn print() {
    for p in ["/tmp/scene_dev/s/room.toml"] {
        if let Err(e) = lensmap::scene::Scene::load(std::path::Path::new(p)) { eprintln!("{e}"); }
    }
    let text = std::fs::read_to_string("/tmp/scene_dev/s/room.toml").unwrap().replace("spheer", "sphere");
    if let Err(e) = lensmap::scene::Scene::from_toml_str(&text, std::path::Path::new("scenes/room.toml")) { eprintln!("{e}"); }
    let text = text.replace("ior = 0", "ior = 1.5").replace("[[objects]]", "[[objects]]\ninside_out = 3");
    if let Err(e) = lensmap::scene::Scene::from_toml_str(&text, std::path::Path::new("scenes/room.toml")) { eprintln!("{e}"); }
    let text = text.replace("inside_out = 3", "transform = { scale = \"big\" }");
    if let Err(e) = lensmap::scene::Scene::from_toml_str(&text, std::path::Path::new("scenes/room.toml")) { eprintln!("{e}"); }
    let text = text.replace("transform = { scale = \"big\" }", "[objects.transform]\nrotate = [1,2,3]");
    if let Err(e) = lensmap::scene::Scene::from_toml_str(&text, std::path::Path::new("scenes/room.toml")) { eprintln!("{e}"); }
    let text = "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 1, 0\nvfov_degrees = 3";
    if let Err(e) = lensmap::scene::Scene::from_toml_str(&text, std::path::Path::new("scenes/room.toml")) { eprintln!("{e}"); }
    for name in ["teapot-room", "glass-sphere", "mirror-teapot"] {
        let s = lensmap::scene::Scene::builtin(name).unwrap().unwrap();
        eprintln!("{name}: {} objects, {} triangles, lenses {:?}", s.objects.len(), s.triangle_count(), s.lenses.iter().map(|l| (&l.name, l.objects.iter().map(|&o| s.objects[o].mesh.triangle_count()).sum::<usize>())).collect::<Vec<_>>());
    }
}
