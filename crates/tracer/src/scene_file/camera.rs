//! The `[camera]` section: its form in the file (a pose and optional keyframes that override
//! it) and its building into a [`Camera`], each pose checked.

use serde::Deserialize;

use super::builder::{Builder, Checked, shown};
use crate::camera::{Camera, CameraPose, Keyframe, pose_problem};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSection {
    position: [f64; 3],
    look_at: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    #[serde(default = "default_fov")]
    fov: f64,
    #[serde(default)]
    keyframes: Vec<toml::Value>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

fn default_fov() -> f64 {
    40.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeSection {
    frame: f64,
    position: Option<[f64; 3]>,
    look_at: Option<[f64; 3]>,
    up: Option<[f64; 3]>,
    fov: Option<f64>,
}

impl Builder<'_> {
    /// A keyframe's or the camera's pose, checked.
    fn pose(&self, field: &str, pose: CameraPose) -> Checked<CameraPose> {
        match pose_problem(&pose) {
            None => Ok(pose),
            Some(problem) => self.fail(field, format!("degenerate pose: {problem}")),
        }
    }

    pub(super) fn camera(&self, value: toml::Value) -> Checked<Camera> {
        let c: CameraSection = self.section("camera", value)?;
        let base = CameraPose {
            position: self.point("camera.position", c.position)?,
            look_at: self.point("camera.look_at", c.look_at)?,
            up: self.point("camera.up", c.up)?,
            fov_degrees: c.fov,
        };
        let mut keyframes = vec![];
        if c.keyframes.is_empty() {
            keyframes.push(Keyframe {
                frame: 0.0,
                pose: self.pose("camera", base)?,
            });
        }
        for (i, k) in c.keyframes.into_iter().enumerate() {
            let field = format!("camera.keyframes[{i}]");
            let k: KeyframeSection = self.section(&field, k)?;
            let pose = CameraPose {
                position: k.position.map_or(Ok(base.position), |p| {
                    self.point(&format!("{field}.position"), p)
                })?,
                look_at: k.look_at.map_or(Ok(base.look_at), |p| {
                    self.point(&format!("{field}.look_at"), p)
                })?,
                up: k
                    .up
                    .map_or(Ok(base.up), |p| self.point(&format!("{field}.up"), p))?,
                fov_degrees: k.fov.unwrap_or(base.fov_degrees),
            };
            if !k.frame.is_finite() {
                return self.fail(format!("{field}.frame"), "must be finite");
            }
            // Two poses at one frame would make the camera there depend on their order.
            if let Some(j) = keyframes.iter().position(|other| other.frame == k.frame) {
                return self.fail(
                    format!("{field}.frame"),
                    format!(
                        "frame {} is also camera.keyframes[{j}]'s: each keyframe needs a frame of its own",
                        shown(k.frame)
                    ),
                );
            }
            keyframes.push(Keyframe {
                frame: k.frame,
                pose: self.pose(&field, pose)?,
            });
        }
        match Camera::new(keyframes) {
            Some(camera) => Ok(camera),
            None => self.fail("camera", "a keyframe's pose is degenerate"),
        }
    }
}
