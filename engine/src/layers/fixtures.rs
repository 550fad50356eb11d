//! Small scenes for tests of the layers and of what builds on them (the baker's unit tests,
//! through the `fixtures` feature), written once.

/// A glass ball of radius 0.5 m at the origin before a white 2.2 m panel 2 m behind it, under a
/// constant sky, seen from 3 m at 16×16 pixels; the ball is a lens object with two named layers:
/// spheres of 2 m (holding the panel) and 50 m (the sky).
pub const BALL_BEFORE_PANEL: &str = r#"
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
vfov_degrees = 40.0
width = 16
height = 16

[environment]
constant = [0.2, 0.4, 0.6]

[[materials]]
name = "glass"
glass = { ior = 1.5 }

[[materials]]
name = "white"
diffuse = { colour = [1.0, 1.0, 1.0] }

[[objects]]
name = "ball"
material = "glass"
sphere = { radius = 0.5 }

[[objects]]
name = "panel"
material = "white"
plane = { size = [2.2, 2.2] }
transform = { rotate_degrees = [90, 0, 0], translate = [0.0, 0.0, -2.0] }

[[lenses]]
name = "ball"
objects = ["ball"]
layers = [{ sphere = 2.0 }, { sphere = 50.0 }]
"#;
