//! Linear RGB images: reading PNG (sRGB-decoded) and EXR textures, bilinear lookup with
//! wrapping, and writing linear EXR and tone-mapped sRGB PNG.

use std::path::Path;

use glam::{DVec2, DVec3};

use crate::error::TracerError;
use crate::limits;
use crate::settings::PixelBounds;

/// Checks an image's size from its header against [`limits::MAX_IMAGE_SIDE`] and
/// [`limits::MAX_IMAGE_PIXELS`].
fn check_size(width: usize, height: usize) -> Result<(), String> {
    let side = limits::MAX_IMAGE_SIDE;
    let most = limits::MAX_IMAGE_PIXELS;
    if width > side || height > side {
        return Err(format!(
            "{width} × {height} pixels: wider or higher than the limit of {side}"
        ));
    }
    if width.saturating_mul(height) > most {
        return Err(format!(
            "{width} × {height} pixels: more than the limit of {most} pixels"
        ));
    }
    Ok(())
}

/// What a PNG's 8- or 16-bit values mean (an EXR's values are linear either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PngValues {
    /// sRGB-encoded colour, decoded to linear (colour textures, tints, lights).
    Srgb,
    /// Linear data, read as value / (2^bits − 1) (density and roughness maps).
    Linear,
}

/// A linear RGB image, row-major from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The pixels.
    pub pixels: Vec<DVec3>,
}

/// The sRGB transfer function's inverse: an 8-bit-style encoded value to linear.
#[must_use]
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function: linear to encoded, for c in [0, 1].
#[must_use]
pub fn linear_to_srgb(c: f64) -> f64 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// For a palette PNG, an error naming the first pixel whose index lies beyond the palette
/// (decoders expand such an index to black, silently); other PNGs pass untouched. Decodes the
/// indices once, unexpanded.
fn check_palette_indices(bytes: &[u8]) -> Result<(), String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let info = reader.info();
    if info.color_type != png::ColorType::Indexed {
        return Ok(());
    }
    let entries = info.palette.as_ref().map_or(0, |p| p.len() / 3);
    let (width, height) = (info.width as usize, info.height as usize);
    check_size(width, height)?;
    let bits = info.bit_depth as usize;
    let size = reader
        .output_buffer_size()
        .ok_or("the image is too large")?;
    let mut buffer = vec![0u8; size];
    let frame = reader.next_frame(&mut buffer).map_err(|e| e.to_string())?;
    for (y, row) in buffer
        .chunks(frame.line_size.max(1))
        .take(height)
        .enumerate()
    {
        for x in 0..width {
            let bit = x * bits;
            let index = usize::from(row[bit / 8] >> (8 - bits - bit % 8)) & ((1 << bits) - 1);
            if index >= entries {
                return Err(format!(
                    "pixel ({x}, {y}) is palette index {index}, beyond the palette's {entries} \
                     entries"
                ));
            }
        }
    }
    Ok(())
}

impl RgbImage {
    /// An image of one colour.
    #[must_use]
    pub fn filled(width: usize, height: usize, colour: DVec3) -> Self {
        Self {
            width,
            height,
            pixels: vec![colour; width * height],
        }
    }

    /// Loads a PNG (8 or 16 bits, grey or colour, alpha ignored; decoded from sRGB) or an
    /// OpenEXR file (linear), chosen by the extension. The file must be a regular file of at
    /// most [`limits::MAX_IMAGE_FILE_BYTES`], and the image at most
    /// [`limits::MAX_IMAGE_SIDE`] pixels wide and high and [`limits::MAX_IMAGE_PIXELS`] in all,
    /// as its header says (checked before the pixels are allocated).
    ///
    /// # Errors
    /// [`TracerError::Asset`] naming the file and the problem.
    pub fn load(path: &Path) -> Result<Self, TracerError> {
        Self::load_as(path, PngValues::Srgb)
    }

    /// [`RgbImage::load`], a PNG's values read as `values` say (sRGB colour or linear data).
    ///
    /// # Errors
    /// [`TracerError::Asset`] naming the file and the problem.
    pub fn load_as(path: &Path, values: PngValues) -> Result<Self, TracerError> {
        let error = |problem: String| TracerError::Asset {
            path: path.to_path_buf(),
            problem,
        };
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let png = match extension.as_deref() {
            Some("png") => true,
            Some("exr") => false,
            _ => return Err(error("unknown image format (expected .png or .exr)".into())),
        };
        let bytes = limits::read_file(path, limits::MAX_IMAGE_FILE_BYTES).map_err(error)?;
        if png {
            Self::from_png_bytes_as(&bytes, values).map_err(error)
        } else {
            Self::from_exr_bytes(&bytes).map_err(error)
        }
    }

    /// Decodes a PNG held in memory, as [`RgbImage::load`] does.
    ///
    /// # Errors
    /// The problem: not a PNG, larger than the limits, truncated, empty.
    pub fn from_png_bytes(bytes: &[u8]) -> Result<Self, String> {
        Self::from_png_bytes_as(bytes, PngValues::Srgb)
    }

    /// Decodes a PNG held in memory, its values read as `values` say.
    ///
    /// # Errors
    /// As [`RgbImage::from_png_bytes`].
    pub fn from_png_bytes_as(bytes: &[u8], values: PngValues) -> Result<Self, String> {
        let decode = match values {
            PngValues::Srgb => srgb_to_linear,
            PngValues::Linear => |c: f64| c,
        };
        check_palette_indices(bytes)?;
        let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        decoder.set_transformations(png::Transformations::EXPAND);
        let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
        let (width, height) = (reader.info().width as usize, reader.info().height as usize);
        check_size(width, height)?;
        let size = reader
            .output_buffer_size()
            .ok_or("the image is too large")?;
        let mut buffer = vec![0u8; size];
        let info = reader.next_frame(&mut buffer).map_err(|e| e.to_string())?;
        let channels = info.color_type.samples();
        let bytes_per_sample = match info.bit_depth {
            png::BitDepth::Sixteen => 2,
            _ => 1,
        };
        let (width, height) = (info.width as usize, info.height as usize);
        check_size(width, height)?;
        let row_samples = width * channels;
        // Every sample code's decoded value, once, where the image has more samples than codes
        // (the sRGB curve costs a power per sample: an eighth of a 4096²-texel map's load).
        let largest_code: u16 = if bytes_per_sample == 2 { 65535 } else { 255 };
        let value_of = |code: u16| decode(f64::from(code) / f64::from(largest_code));
        let decoded: Vec<f64> = if width * height * channels > usize::from(largest_code) {
            (0..=largest_code).map(value_of).collect()
        } else {
            Vec::new()
        };
        let sample = |code: u16| {
            decoded
                .get(usize::from(code))
                .copied()
                .unwrap_or_else(|| value_of(code))
        };
        let mut pixels = Vec::with_capacity(width * height);
        for row in buffer.chunks(info.line_size.max(1)).take(height) {
            let samples: Vec<f64> = if bytes_per_sample == 2 {
                row.chunks_exact(2)
                    .take(row_samples)
                    .map(|b| sample(u16::from_be_bytes([b[0], b[1]])))
                    .collect()
            } else {
                row.iter()
                    .take(row_samples)
                    .map(|&b| sample(u16::from(b)))
                    .collect()
            };
            if samples.len() < row_samples {
                return Err("the decoded rows are shorter than the image".into());
            }
            for texel in samples.chunks_exact(channels) {
                let rgb = if channels >= 3 {
                    DVec3::new(texel[0], texel[1], texel[2])
                } else {
                    DVec3::splat(texel[0])
                };
                pixels.push(rgb);
            }
        }
        Self::checked(width, height, pixels)
    }

    /// Decodes an OpenEXR file held in memory (its first RGBA layer, linear; a grey file of one
    /// `Y` channel gives Y in every channel), as
    /// [`RgbImage::load`] does.
    ///
    /// # Errors
    /// The problem: not an EXR, a layer larger than the limits, damaged, non-finite pixels.
    pub fn from_exr_bytes(bytes: &[u8]) -> Result<Self, String> {
        use exr::prelude::*;
        // Every layer's size from the headers, before the reader allocates pixels for one.
        let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
            .map_err(|e| e.to_string())?;
        for header in &meta.headers {
            check_size(header.layer_size.width(), header.layer_size.height())?;
        }
        let named = |name: &str| {
            meta.headers
                .iter()
                .any(|h| h.channels.list.iter().any(|c| c.name.to_string() == name))
        };
        if !named("R") && !named("G") && !named("B") && named("Y") {
            if named("RY") || named("BY") {
                return Err(
                    "a luminance-chroma EXR (Y, RY, BY) is not read: save it as RGB".into(),
                );
            }
            return Self::from_luminance_exr_bytes(bytes);
        }
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |resolution, _| {
                    // Within the limits: every header was checked above.
                    let (w, h) = (resolution.width(), resolution.height());
                    RgbImage::filled(w, h, DVec3::ZERO)
                },
                |image: &mut RgbImage, position, (r, g, b, _a): (f32, f32, f32, f32)| {
                    let i = position.y() * image.width + position.x();
                    if let Some(p) = image.pixels.get_mut(i) {
                        *p = DVec3::new(r.into(), g.into(), b.into());
                    }
                },
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
            .map_err(|e| e.to_string())?;
        let pixels = image.layer_data.channel_data.pixels;
        Self::checked(pixels.width, pixels.height, pixels.pixels)
    }

    /// Decodes a grey OpenEXR file (a luminance channel `Y` and no R, G, B) as an image whose
    /// three channels are Y, the first layer that has it.
    fn from_luminance_exr_bytes(bytes: &[u8]) -> Result<Self, String> {
        use exr::prelude::*;
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required("Y")
            .collect_pixels(
                |resolution, _| {
                    let (w, h) = (resolution.width(), resolution.height());
                    RgbImage::filled(w, h, DVec3::ZERO)
                },
                |image: &mut RgbImage, position, (y,): (f32,)| {
                    let i = position.y() * image.width + position.x();
                    if let Some(p) = image.pixels.get_mut(i) {
                        *p = DVec3::splat(y.into());
                    }
                },
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
            .map_err(|e| e.to_string())?;
        let pixels = image.layer_data.channel_data.pixels;
        Self::checked(pixels.width, pixels.height, pixels.pixels)
    }

    /// The image, unless it is empty, its pixels do not match its size, or one is not finite.
    fn checked(width: usize, height: usize, pixels: Vec<DVec3>) -> Result<Self, String> {
        if width == 0 || height == 0 {
            return Err("the image is empty".into());
        }
        if pixels.len() != width * height {
            return Err(format!(
                "{} pixels decoded for {width} × {height}",
                pixels.len()
            ));
        }
        if let Some(i) = pixels.iter().position(|p| !p.is_finite()) {
            return Err(format!(
                "pixel ({}, {}) is not finite",
                i % width,
                i / width
            ));
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// The largest texel value of any channel.
    #[must_use]
    pub fn max_value(&self) -> f64 {
        self.pixels
            .iter()
            .map(|p| p.max_element())
            .fold(0.0, f64::max)
    }

    /// The texel at integer coordinates, wrapped.
    #[must_use]
    pub fn texel(&self, x: i64, y: i64) -> DVec3 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.pixels[y * self.width + x]
    }

    /// Bilinear lookup at texture coordinates `uv` (v = 0 at the bottom row, as in OBJ and
    /// the rectangle's parameterization), repeating.
    #[must_use]
    pub fn lookup(&self, uv: DVec2) -> DVec3 {
        self.bilinear(uv, false)
    }

    /// Bilinear lookup for a lat-long map: columns wrap (φ is periodic), rows are clamped (the
    /// poles do not meet). `uv` as in [`RgbImage::lookup`].
    #[must_use]
    pub fn lookup_latlong(&self, uv: DVec2) -> DVec3 {
        self.bilinear(uv, true)
    }

    /// Bilinear interpolation between texel centres; columns always wrap, rows wrap unless
    /// `clamp_rows`.
    fn bilinear(&self, uv: DVec2, clamp_rows: bool) -> DVec3 {
        if !uv.is_finite() {
            return DVec3::ZERO;
        }
        let x = uv.x * self.width as f64 - 0.5;
        let mut y = (1.0 - uv.y) * self.height as f64 - 0.5;
        if clamp_rows {
            y = y.clamp(0.0, (self.height - 1) as f64);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let y1 = if clamp_rows {
            (y0 + 1).min(self.height as i64 - 1)
        } else {
            y0 + 1
        };
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y1).lerp(self.texel(x0 + 1, y1), fx);
        top.lerp(bottom, fy)
    }

    /// The mean colour.
    #[must_use]
    pub fn mean(&self) -> DVec3 {
        self.pixels.iter().copied().sum::<DVec3>() / self.pixels.len().max(1) as f64
    }

    /// Bloom, a display post-process (the paper's Fig. 7): the light above `threshold` in each
    /// channel, blurred by a Gaussian of standard deviation `radius` pixels, times `strength`,
    /// added to the image. It shows how bright the glints are beyond the display's range.
    #[must_use]
    pub fn bloomed(&self, threshold: f64, radius: f64, strength: f64) -> Self {
        let excess: Vec<DVec3> = self
            .pixels
            .iter()
            .map(|p| (*p - DVec3::splat(threshold)).max(DVec3::ZERO))
            .collect();
        let half = (3.0 * radius).ceil().max(1.0) as i64;
        let kernel: Vec<f64> = (-half..=half)
            .map(|k| (-0.5 * (k as f64 / radius.max(1e-3)).powi(2)).exp())
            .collect();
        let total: f64 = kernel.iter().sum();
        let (w, h) = (self.width as i64, self.height as i64);
        let blur = |source: &[DVec3], step: (i64, i64)| -> Vec<DVec3> {
            let mut out = vec![DVec3::ZERO; source.len()];
            for y in 0..h {
                for x in 0..w {
                    let mut sum = DVec3::ZERO;
                    for (i, weight) in kernel.iter().enumerate() {
                        let k = i as i64 - half;
                        let (sx, sy) = (x + k * step.0, y + k * step.1);
                        if (0..w).contains(&sx) && (0..h).contains(&sy) {
                            sum += source[(sy * w + sx) as usize] * *weight;
                        }
                    }
                    out[(y * w + x) as usize] = sum / total;
                }
            }
            out
        };
        let glow = blur(&blur(&excess, (1, 0)), (0, 1));
        Self {
            width: self.width,
            height: self.height,
            pixels: self
                .pixels
                .iter()
                .zip(&glow)
                .map(|(p, g)| *p + *g * strength)
                .collect(),
        }
    }

    /// Images placed left to right, top-aligned, on black.
    #[must_use]
    pub fn side_by_side(images: &[&Self]) -> Self {
        let width = images.iter().map(|i| i.width).sum();
        let height = images.iter().map(|i| i.height).max().unwrap_or(0);
        let mut out = Self::filled(width, height, DVec3::ZERO);
        let mut x0 = 0;
        for image in images {
            for y in 0..image.height {
                for x in 0..image.width {
                    out.pixels[y * width + x0 + x] = image.pixels[y * image.width + x];
                }
            }
            x0 += image.width;
        }
        out
    }

    /// The image shrunk by an integer `factor` (box filter over factor × factor blocks).
    #[must_use]
    pub fn downsampled(&self, factor: usize) -> Self {
        let factor = factor.max(1);
        let (width, height) = ((self.width / factor).max(1), (self.height / factor).max(1));
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let mut sum = DVec3::ZERO;
                let mut n = 0.0;
                for sy in y * factor..((y + 1) * factor).min(self.height) {
                    for sx in x * factor..((x + 1) * factor).min(self.width) {
                        sum += self.pixels[sy * self.width + sx];
                        n += 1.0;
                    }
                }
                pixels.push(sum / n);
            }
        }
        Self {
            width,
            height,
            pixels,
        }
    }

    /// Writes a linear 32-bit float RGB OpenEXR file.
    ///
    /// # Errors
    /// As [`RgbImage::write_exr_in`].
    pub fn write_exr(&self, path: &Path) -> Result<(), TracerError> {
        let (width, height) = (self.width as u32, self.height as u32);
        self.write_exr_in(path, PixelBounds::full(width, height), width, height)
    }

    /// Writes a linear 32-bit float RGB OpenEXR file of the pixels `bounds` of a `width` ×
    /// `height` image: OpenEXR's data window is the bounds, its display window the whole image
    /// (as pbrt writes crops), so the file records where its pixels belong.
    ///
    /// # Errors
    /// [`TracerError::Output`] when the file cannot be written, when the bounds do not match
    /// the image's size or lie outside `width` × `height`, or when a pixel is not finite or
    /// beyond the 32-bit float range (it would be written as infinity); rendered images never
    /// are (see [`crate::render`]).
    pub fn write_exr_in(
        &self,
        path: &Path,
        bounds: PixelBounds,
        width: u32,
        height: u32,
    ) -> Result<(), TracerError> {
        use exr::prelude::{
            Encoding, Image, ImageAttributes, IntegerBounds, Layer, LayerAttributes,
            SpecificChannels, Vec2, WritableImage,
        };
        let error = |problem: String| TracerError::Output {
            path: path.to_path_buf(),
            problem,
        };
        if let Some(problem) = bounds.problem(width, height) {
            return Err(error(format!("pixel bounds {problem}")));
        }
        if (bounds.width() as usize, bounds.height() as usize) != (self.width, self.height) {
            return Err(error(format!(
                "the image is {}x{} but its pixel bounds cover {}x{}",
                self.width,
                self.height,
                bounds.width(),
                bounds.height()
            )));
        }
        let largest = f64::from(f32::MAX);
        if let Some(i) = self
            .pixels
            .iter()
            .position(|p| !(p.is_finite() && p.abs().max_element() <= largest))
        {
            return Err(error(format!(
                "pixel ({}, {}) is {}: not a finite 32-bit float",
                i % self.width.max(1),
                i / self.width.max(1),
                limits::vector(self.pixels[i])
            )));
        }
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p = self.pixels[y * self.width + x];
            (p.x as f32, p.y as f32, p.z as f32)
        });
        // Within OpenEXR's i32 coordinates: sizes are at most 16384 (checked by the film).
        let corner = Vec2(bounds.x0 as i32, bounds.y0 as i32);
        let layer = Layer::new(
            (self.width, self.height),
            LayerAttributes {
                layer_position: corner,
                ..LayerAttributes::default()
            },
            Encoding::default(),
            channels,
        );
        let display = IntegerBounds::new((0, 0), (width as usize, height as usize));
        // Sequential compression: parallel compression writes the chunks in the order they
        // finish, so the same pixels would give different files from run to run.
        Image::new(ImageAttributes::new(display), layer)
            .write()
            .non_parallel()
            .to_file(path)
            .map_err(|e| error(e.to_string()))
    }

    /// The 8-bit sRGB encoding of the image scaled by 2^`exposure` (clamped to [0, 1]).
    #[must_use]
    pub fn to_srgb8(&self, exposure: f64) -> Vec<u8> {
        let scale = exposure.exp2();
        let encode = |c: f64| {
            let c = if c.is_finite() {
                (c * scale).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (linear_to_srgb(c) * 255.0 + 0.5) as u8
        };
        self.pixels
            .iter()
            .flat_map(|p| [encode(p.x), encode(p.y), encode(p.z)])
            .collect()
    }

    /// The tone-mapped 8-bit sRGB PNG (exposure 2^`exposure`, clamped) as bytes.
    ///
    /// # Errors
    /// The encoder's message (only for images too large for PNG).
    pub fn encode_png(&self, exposure: f64) -> Result<Vec<u8>, String> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer
            .write_image_data(&self.to_srgb8(exposure))
            .map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())?;
        Ok(bytes)
    }

    /// The image as data: an 8-bit RGB PNG of round(255·c) per channel, c clamped to [0, 1],
    /// without sRGB encoding (what [`PngValues::Linear`] reads back).
    ///
    /// # Errors
    /// The encoder's message (only for images too large for PNG).
    pub fn encode_png_linear(&self) -> Result<Vec<u8>, String> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        let data: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| p.to_array())
            .map(|c| {
                let c = if c.is_finite() {
                    c.clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (c * 255.0).round() as u8
            })
            .collect();
        writer.write_image_data(&data).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())?;
        Ok(bytes)
    }

    /// Writes a tone-mapped 8-bit sRGB PNG (exposure 2^`exposure`, clamped).
    ///
    /// # Errors
    /// [`TracerError::Output`] when the file cannot be written.
    pub fn write_png(&self, path: &Path, exposure: f64) -> Result<(), TracerError> {
        let error = |problem: String| TracerError::Output {
            path: path.to_path_buf(),
            problem,
        };
        let bytes = self.encode_png(exposure).map_err(error)?;
        std::fs::write(path, bytes).map_err(|e| error(e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> RgbImage {
        let (width, height) = (5, 3);
        let pixels = (0..width * height)
            .map(|i| DVec3::new((i % width) as f64 / 4.0, (i / width) as f64 / 2.0, 0.25))
            .collect();
        RgbImage {
            width,
            height,
            pixels,
        }
    }

    #[test]
    fn exr_files_are_byte_identical_for_identical_pixels() {
        // Enough scan-line chunks (16 lines each) that parallel compression would reorder them.
        let (width, height) = (512, 512);
        let pixels = (0..width * height)
            .map(|i| DVec3::new((i * 7919 % 1000) as f64 / 999.0, (i % width) as f64, 0.5))
            .collect();
        let image = RgbImage {
            width,
            height,
            pixels,
        };
        let dir = std::env::temp_dir().join(format!("glint-exr-bytes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files: Vec<Vec<u8>> = (0..3)
            .map(|k| {
                let path = dir.join(format!("{k}.exr"));
                image.write_exr(&path).unwrap();
                std::fs::read(&path).unwrap()
            })
            .collect();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(files.iter().all(|f| *f == files[0]));
    }

    #[test]
    fn png_and_exr_round_trip() {
        let dir = std::env::temp_dir().join(format!("glint-image-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let image = gradient();
        let exr_path = dir.join("g.exr");
        image.write_exr(&exr_path).unwrap();
        let back = RgbImage::load(&exr_path).unwrap();
        assert_eq!((back.width, back.height), (5, 3));
        for (a, b) in image.pixels.iter().zip(&back.pixels) {
            assert!((*a - *b).abs().max_element() < 1e-6);
        }
        let png_path = dir.join("g.png");
        image.write_png(&png_path, 0.0).unwrap();
        let back = RgbImage::load(&png_path).unwrap();
        for (a, b) in image.pixels.iter().zip(&back.pixels) {
            // 8-bit sRGB quantization: at most half a step, ≤ 0.5/255 / (dlinear/dsrgb ≥ 12.92⁻¹…).
            assert!((*a - *b).abs().max_element() < 6e-3, "{a} {b}");
        }
        let missing = RgbImage::load(&dir.join("nope.png"));
        assert!(matches!(missing, Err(TracerError::Asset { .. })));
        let wrong = RgbImage::load(&dir.join("g.bmp"));
        assert!(
            wrong
                .unwrap_err()
                .to_string()
                .contains("unknown image format")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Every 8-bit code, and 16-bit codes across the range, decode to the transfer function of
    /// code / (2^bits − 1) bit for bit: sRGB through `srgb_to_linear`, linear as the fraction
    /// (the 8-bit image, of more samples than codes, through the table of codes; the 16-bit one
    /// code by code).
    #[test]
    fn png_codes_decode_by_the_transfer_function() {
        let mut codes_16: Vec<u16> = (0..=65535u32)
            .step_by(257 * 3 + 1)
            .map(|c| c as u16)
            .collect();
        codes_16.push(65535);
        for sixteen in [false, true] {
            let codes: Vec<u32> = if sixteen {
                codes_16.iter().map(|&c| u32::from(c)).collect()
            } else {
                (0..=255).collect()
            };
            let mut bytes = Vec::new();
            {
                let mut encoder = png::Encoder::new(&mut bytes, codes.len() as u32, 1);
                encoder.set_color(png::ColorType::Grayscale);
                encoder.set_depth(if sixteen {
                    png::BitDepth::Sixteen
                } else {
                    png::BitDepth::Eight
                });
                let mut writer = encoder.write_header().unwrap();
                let data: Vec<u8> = if sixteen {
                    codes
                        .iter()
                        .flat_map(|&c| (c as u16).to_be_bytes())
                        .collect()
                } else {
                    codes.iter().map(|&c| c as u8).collect()
                };
                writer.write_image_data(&data).unwrap();
            }
            let largest = if sixteen { 65535.0 } else { 255.0 };
            for (values, decode) in [
                (PngValues::Srgb, srgb_to_linear as fn(f64) -> f64),
                (PngValues::Linear, |c: f64| c),
            ] {
                let image = RgbImage::from_png_bytes_as(&bytes, values).unwrap();
                for (&code, pixel) in codes.iter().zip(&image.pixels) {
                    let expected = decode(f64::from(code) / largest);
                    assert_eq!(*pixel, DVec3::splat(expected), "code {code} of {largest}");
                }
            }
        }
    }

    /// A grey EXR of one `Y` channel loads with Y in every channel (it was refused for lacking
    /// R, G and B).
    #[test]
    fn luminance_exr_files_load_as_grey() {
        use exr::prelude::*;
        let pixels = SpecificChannels::build()
            .with_channel("Y")
            .with_pixel_fn(|p: Vec2<usize>| (p.x() as f32 * 0.25 + p.y() as f32,));
        let mut bytes = Vec::new();
        Image::from_channels((3, 2), pixels)
            .write()
            .to_buffered(std::io::Cursor::new(&mut bytes))
            .unwrap();
        let image = RgbImage::from_exr_bytes(&bytes).unwrap();
        assert_eq!((image.width, image.height), (3, 2));
        for (i, p) in image.pixels.iter().enumerate() {
            let y = (i % 3) as f64 * 0.25 + (i / 3) as f64;
            assert_eq!(*p, DVec3::splat(y), "pixel {i}");
        }
    }

    /// A palette PNG whose pixel indexes past its palette is refused naming the pixel (it
    /// loaded as black); indices within the palette load, at every bit depth.
    #[test]
    fn palette_indices_beyond_the_palette_are_refused() {
        let encode = |depth: png::BitDepth, palette: &[u8], rows: &[u8]| {
            let mut bytes = Vec::new();
            let mut encoder = png::Encoder::new(&mut bytes, 4, 2);
            encoder.set_color(png::ColorType::Indexed);
            encoder.set_depth(depth);
            encoder.set_palette(palette.to_vec());
            encoder
                .write_header()
                .unwrap()
                .write_image_data(rows)
                .unwrap();
            bytes
        };
        let palette = [0, 0, 0, 255, 255, 255];
        // 8 bits: one byte a pixel; index 2 at pixel (1, 1).
        let good = encode(png::BitDepth::Eight, &palette, &[0, 1, 1, 0, 1, 0, 0, 1]);
        let image = RgbImage::from_png_bytes(&good).unwrap();
        assert_eq!(image.pixels[1], DVec3::ONE);
        let bad = encode(png::BitDepth::Eight, &palette, &[0, 1, 1, 0, 1, 2, 0, 1]);
        let message = RgbImage::from_png_bytes(&bad).unwrap_err();
        assert!(
            message.contains("pixel (1, 1) is palette index 2"),
            "{message}"
        );
        // 2 bits: four pixels a byte, the first in the high bits; index 3 at pixel (2, 0).
        let bad = encode(png::BitDepth::Two, &palette, &[0b0001_1100, 0b0100_0001]);
        let message = RgbImage::from_png_bytes(&bad).unwrap_err();
        assert!(
            message.contains("pixel (2, 0) is palette index 3"),
            "{message}"
        );
        let good = encode(png::BitDepth::Two, &palette, &[0b0001_0100, 0b0100_0001]);
        let image = RgbImage::from_png_bytes(&good).unwrap();
        assert_eq!(image.pixels[1], DVec3::ONE);
    }

    /// An image's size is checked against the limits from its header, before its pixels are
    /// allocated: a PNG of 2 KB whose header claims 60000 × 60000 pixels (it asked for 10.8 GB),
    /// one within the side limit but over the pixel limit, an EXR whose data window claims
    /// 60000 × 60000; each is an error naming the file and the size.
    #[test]
    fn image_sizes_are_checked_from_the_header() {
        use crate::fuzz::{patch_exr_data_window, patch_png_size, small_exr, small_png};
        let dir = std::env::temp_dir().join(format!("glint-image-size-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let png = small_png(4, 3);
        assert_eq!(RgbImage::from_png_bytes(&png).unwrap().pixels.len(), 12);
        for (width, height, words) in [
            (60_000, 60_000, "wider or higher than the limit of 16384"),
            (16_384, 16_384, "more than the limit of 67108864 pixels"),
        ] {
            let mut crafted = png.clone();
            patch_png_size(&mut crafted, width, height, true);
            let path = dir.join(format!("{width}.png"));
            std::fs::write(&path, &crafted).unwrap();
            let message = RgbImage::load(&path).unwrap_err().to_string();
            assert!(message.contains(&format!("{width}.png")), "{message}");
            assert!(message.contains(words), "{message}");
        }
        let exr = small_exr(&dir);
        assert_eq!(RgbImage::from_exr_bytes(&exr).unwrap().pixels.len(), 15);
        let mut crafted = exr;
        patch_exr_data_window(&mut crafted, 59_999, 59_999);
        let path = dir.join("huge.exr");
        std::fs::write(&path, &crafted).unwrap();
        let message = RgbImage::load(&path).unwrap_err().to_string();
        assert!(message.contains("huge.exr"), "{message}");
        assert!(message.contains("60000 × 60000"), "{message}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Pixels that single precision cannot hold are refused when an EXR is written, never
    /// written as infinities.
    /// A crop's EXR records where it belongs: its data window is the bounds, its display
    /// window the full image, and it reads back as the crop's pixels. Bounds that do not match
    /// the image are refused.
    #[test]
    fn crop_exr_files_record_their_bounds() {
        let dir = std::env::temp_dir().join(format!("glint-exr-crop-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let image = gradient();
        let (w, h) = (image.width as u32, image.height as u32);
        let bounds = PixelBounds {
            x0: 5,
            x1: 5 + w,
            y0: 7,
            y1: 7 + h,
        };
        let path = dir.join("crop.exr");
        image.write_exr_in(&path, bounds, 40, 30).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let meta =
            exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false).unwrap();
        let header = &meta.headers[0];
        assert_eq!(header.own_attributes.layer_position, exr::math::Vec2(5, 7));
        assert_eq!(header.layer_size, exr::math::Vec2(w as usize, h as usize));
        assert_eq!(
            header.shared_attributes.display_window,
            exr::meta::attribute::IntegerBounds::new((0, 0), (40, 30))
        );
        let back = RgbImage::from_exr_bytes(&bytes).unwrap();
        assert_eq!((back.width, back.height), (image.width, image.height));
        for (a, b) in back.pixels.iter().zip(&image.pixels) {
            assert_eq!(*a, a.as_vec3().as_dvec3());
            assert!((*a - *b).abs().max_element() <= 1e-6 * b.abs().max_element());
        }
        let outside = PixelBounds {
            x1: 41 + w,
            ..bounds
        };
        assert!(image.write_exr_in(&path, outside, 40, 30).is_err());
        let mismatched = PixelBounds {
            x1: 4 + w,
            ..bounds
        };
        let error = image.write_exr_in(&path, mismatched, 40, 30).unwrap_err();
        assert!(error.to_string().contains("pixel bounds cover"), "{error}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn exr_output_refuses_non_finite_pixels() {
        let dir = std::env::temp_dir().join(format!("glint-exr-inf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for bad in [f64::INFINITY, f64::NAN, 1e39] {
            let mut image = gradient();
            image.pixels[7] = DVec3::new(0.5, bad, 0.5);
            let message = image
                .write_exr(&dir.join("bad.exr"))
                .unwrap_err()
                .to_string();
            assert!(message.contains("pixel (2, 1)"), "{message}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bilinear_lookup_hits_texel_centres_and_wraps() {
        let image = gradient();
        // Texel (x, y) has its centre at u = (x + ½)/w, v = 1 − (y + ½)/h.
        for y in 0..3 {
            for x in 0..5 {
                let uv = DVec2::new((x as f64 + 0.5) / 5.0, 1.0 - (y as f64 + 0.5) / 3.0);
                assert!((image.lookup(uv) - image.texel(x, y)).length() < 1e-12);
                assert!(
                    (image.lookup(uv + DVec2::new(2.0, -3.0)) - image.texel(x, y)).length() < 1e-9
                );
            }
        }
        assert_eq!(image.lookup(DVec2::new(f64::NAN, 0.0)), DVec3::ZERO);
        // Lat-long lookups do not blend the top row with the bottom one at the poles.
        let top_row = image.texel(0, 0).lerp(image.texel(1, 0), 0.0);
        assert!((image.lookup_latlong(DVec2::new(0.1, 1.0)) - top_row).length() < 1e-12);
        let bottom_row = image.texel(0, 2);
        assert!((image.lookup_latlong(DVec2::new(0.1, 0.0)) - bottom_row).length() < 1e-12);
    }

    #[test]
    fn bloom_spreads_only_the_excess_and_keeps_its_energy() {
        let mut image = RgbImage::filled(41, 41, DVec3::splat(0.5));
        image.pixels[20 * 41 + 20] = DVec3::splat(10.5);
        let bloomed = image.bloomed(1.0, 2.0, 1.0);
        // Far from the bright pixel nothing changes; the added light sums to the excess (9.5),
        // since the kernel fits inside the image.
        assert_eq!(bloomed.pixels[0], DVec3::splat(0.5));
        let added: f64 = bloomed
            .pixels
            .iter()
            .zip(&image.pixels)
            .map(|(b, a)| b.x - a.x)
            .sum();
        assert!((added - 9.5).abs() < 1e-9, "{added}");
        let pair = RgbImage::side_by_side(&[&image, &bloomed]);
        assert_eq!((pair.width, pair.height), (82, 41));
        assert_eq!(pair.pixels[41 + 20 * 82 + 20], bloomed.pixels[20 * 41 + 20]);
        let small = image.downsampled(4);
        assert_eq!((small.width, small.height), (10, 10));
        // The 10 × 10 blocks cover the top-left 40 × 40 texels, the bright one among them.
        let expected = (0.5 * 1599.0 + 10.5) / 1600.0;
        assert!((small.mean().x - expected).abs() < 1e-12);
    }

    #[test]
    fn srgb_round_trip() {
        for i in 0..=100 {
            let c = f64::from(i) / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(c)) - c).abs() < 1e-12);
        }
    }
}
