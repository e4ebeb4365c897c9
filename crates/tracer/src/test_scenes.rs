//! Small scenes shared by the tracer's unit tests.

/// A glittery floor under a sphere light, path traced with the Gaussian filter.
pub(crate) const GLITTER_FLOOR: &str = r#"
[render]
resolution = [40, 24]
spp = 2
[camera]
position = [0, 1, 3]
look_at = [0, 0, 0]
[materials.glitter]
type = "glint"
alpha = 0.1
particles = 1e7
gamma = 1
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [4, 0, 0]
v = [0, 0, -4]
material = "glitter"
[[lights]]
type = "sphere"
center = [0, 1, -2]
radius = 0.1
power = 20
"#;
