//! What a scene may use ([`crate::limits`]): the [`Budget`] of asset bytes, image pixels and
//! material parts it has spent, and the checks that spend it (asset files, images, primitives).

use std::cell::{Cell, RefCell};
use std::path::{Path, PathBuf};

use super::builder::{Builder, Checked};
use crate::error::TracerError;
use crate::image::{PngValues, RgbImage};
use crate::limits;

/// What a scene has used of its budgets ([`crate::limits`]): asset bytes, image pixels,
/// material parts.
#[derive(Debug, Default)]
pub(super) struct Budget {
    asset_bytes: Cell<u64>,
    /// Every asset file read, in order.
    pub(super) assets: RefCell<Vec<PathBuf>>,
    pixels: Cell<usize>,
    pub(super) material_parts: Cell<usize>,
}

impl Builder<'_> {
    /// Checks that `bytes` more asset bytes fit the scene's budget, and counts them.
    pub(super) fn spend_asset_bytes(&self, field: &str, path: &Path) -> Checked<()> {
        // A file that cannot be inspected is reported by its reader.
        let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
        let total = self.budget.asset_bytes.get().saturating_add(bytes);
        if total > limits::MAX_SCENE_ASSET_BYTES {
            return self.fail(
                field,
                format!(
                    "the scene's assets exceed {} bytes together",
                    limits::MAX_SCENE_ASSET_BYTES
                ),
            );
        }
        self.budget.asset_bytes.set(total);
        self.budget.assets.borrow_mut().push(path.to_path_buf());
        Ok(())
    }

    /// The colour image `relative` (a PNG sRGB-decoded) used at `field`, within the budgets.
    pub(super) fn image(&self, field: &str, relative: &str) -> Checked<RgbImage> {
        self.image_as(field, relative, PngValues::Srgb)
    }

    /// The image `relative` used at `field`, a PNG's values read as `values` say, within the
    /// budgets (its bytes and pixels counted, its path listed among the scene's assets).
    pub(super) fn image_as(
        &self,
        field: &str,
        relative: &str,
        values: PngValues,
    ) -> Checked<RgbImage> {
        let path = self.asset(relative);
        self.spend_asset_bytes(field, &path)?;
        let image = RgbImage::load_as(&path, values).map_err(|e| TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: e.to_string(),
        })?;
        let pixels = self.budget.pixels.get() + image.pixels.len();
        if pixels > limits::MAX_SCENE_PIXELS {
            return self.fail(
                field,
                format!(
                    "the scene's images exceed {} pixels together",
                    limits::MAX_SCENE_PIXELS
                ),
            );
        }
        self.budget.pixels.set(pixels);
        Ok(image)
    }

    /// Checks that `more` primitives fit [`limits::MAX_PRIMITIVES`] after `count`.
    pub(super) fn room_for(&self, field: &str, count: usize, more: usize) -> Checked<()> {
        if count.saturating_add(more) > limits::MAX_PRIMITIVES {
            return self.fail(
                field,
                format!(
                    "the scene would have more than {} primitives (shapes, area lights and triangles)",
                    limits::MAX_PRIMITIVES
                ),
            );
        }
        Ok(())
    }
}
