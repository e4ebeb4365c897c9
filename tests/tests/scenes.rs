//! Every scene under `scenes/` loads and renders at a tiny size, so that no scene file rots:
//! the image is finite, non-negative and not black.

use std::path::Path;

use glint_tracer::render;
use glint_tracer::scene_file::load_scene;

#[test]
fn every_scene_renders_at_a_tiny_size() {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut rendered = 0;
    for entry in std::fs::read_dir(&folder).expect("the scenes folder") {
        let path = entry.expect("a folder entry").path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        let mut settings = scene.settings;
        settings.width = 32;
        settings.height = 18;
        settings.samples_per_pixel = 1;
        settings.max_depth = settings.max_depth.min(2);
        let output = render(&scene, &settings, 0.0, &|_, _| {}).unwrap();
        let pixels = &output.image.pixels;
        assert!(
            pixels
                .iter()
                .all(|p| p.is_finite() && p.min_element() >= 0.0),
            "{}: a pixel is negative or not finite",
            path.display()
        );
        assert!(
            pixels.iter().any(|p| p.max_element() > 0.0),
            "{}: the image is black",
            path.display()
        );
        rendered += 1;
    }
    assert!(
        rendered >= 1,
        "no scene files found in {}",
        folder.display()
    );
}
