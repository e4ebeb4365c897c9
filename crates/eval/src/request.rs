//! The answers to `eval`, `sample` and `pdf` requests from plain numbers, validated as
//! `docs/eval.md` says: directions are normalized (a zero or non-finite vector is an error, a
//! direction below the horizon is valid and gives zeros), footprints must be finite with edges
//! within ±10¹⁵, uniform numbers lie in [0, 1).

use std::sync::atomic::AtomicBool;

use glint_brdf::{DVec2, DVec3, DiscreteBrdf, Footprint, QueryScratch};

use crate::batch::{answer_rows, locality_key};

/// A built material with what its answers need.
#[derive(Clone, Debug)]
pub struct EvalMaterial {
    brdf: DiscreteBrdf,
    gray: bool,
}

/// The inputs of one `eval` request: directions in the local shading frame (z the normal;
/// `wi` toward the viewer, `wo` toward the light) and the footprint
/// {uv + s·duv_dx + t·duv_dy : s, t ∈ [−½, ½]}.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalRow {
    /// ω_i.
    pub wi: [f64; 3],
    /// ω_o.
    pub wo: [f64; 3],
    /// The footprint's centre.
    pub uv: [f64; 2],
    /// Its first edge.
    pub duv_dx: [f64; 2],
    /// Its second edge.
    pub duv_dy: [f64; 2],
}

impl EvalRow {
    /// The row's dispatch key in a batch: [`locality_key`] of its footprint's centre.
    #[must_use]
    pub fn locality_key(&self) -> u64 {
        locality_key(self.uv)
    }
}

/// The answer to an `eval` request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalAnswer {
    /// Particles found.
    pub count: f64,
    /// Their expectation N·a(A)·∫p over the conic.
    pub expected_count: f64,
    /// D̂ of Eq. 6 (its first channel).
    pub d_hat: f64,
    /// f̂ per channel.
    pub f_hat: DVec3,
    /// The smooth BRDF per channel.
    pub f_smooth: DVec3,
    /// Tree nodes visited.
    pub nodes_visited: u32,
    /// `Some(λ̄)` when the query was skipped as negligible.
    pub negligible_bound: Option<f64>,
}

/// Which of an `eval` row's optional answers are computed. f̂, D̂, the count and the nodes
/// visited always are; a column that is off is NaN, and every other column is the same, bit
/// for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EvalColumns {
    /// N·a(A)·∫p over the conic: a tree traversal of its own, as costly as the count's.
    pub expected_count: bool,
    /// The smooth BRDF (Smith's Λ of both directions): about a fifth of a traversed row's
    /// cost. A renderer that shades f̂ wherever it has a footprint does not need it.
    pub f_smooth: bool,
}

impl EvalColumns {
    /// Every column, as `eval` requests and `cargo xtask eval` answer.
    pub const ALL: Self = Self {
        expected_count: true,
        f_smooth: true,
    };
    /// f̂ and what comes with it, without the expected count or the smooth BRDF: what a
    /// renderer shading pixel footprints needs.
    pub const F_HAT: Self = Self {
        expected_count: false,
        f_smooth: false,
    };
}

/// The answer to a `sample` request that sampled a direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleAnswer {
    /// The sampled direction.
    pub wo: DVec3,
    /// Its density.
    pub pdf: f64,
    /// f_smooth·cos θ_o / pdf per channel.
    pub weight: DVec3,
}

impl EvalMaterial {
    pub(crate) fn new(brdf: DiscreteBrdf) -> Self {
        let gray = brdf.is_gray();
        Self { brdf, gray }
    }

    /// The material.
    #[must_use]
    pub fn brdf(&self) -> &DiscreteBrdf {
        &self.brdf
    }

    /// Whether every answer is the same in every channel ([`DiscreteBrdf::is_gray`]): colours
    /// are then one number.
    #[must_use]
    pub fn is_gray(&self) -> bool {
        self.gray
    }

    /// The `eval` request: f̂ for the footprint {uv + s·duv_dx + t·duv_dy : s, t ∈ [−½, ½]}.
    ///
    /// # Errors
    /// A message naming the invalid input (`wi`, `wo`, the footprint).
    pub fn eval(
        &self,
        scratch: &mut QueryScratch,
        wi: [f64; 3],
        wo: [f64; 3],
        uv: [f64; 2],
        duv_dx: [f64; 2],
        duv_dy: [f64; 2],
    ) -> Result<EvalAnswer, String> {
        let row = EvalRow {
            wi,
            wo,
            uv,
            duv_dx,
            duv_dy,
        };
        self.eval_row(scratch, &row, EvalColumns::ALL)
    }

    /// [`EvalMaterial::eval`] of one row, computing the optional `columns` only (the others
    /// are NaN; every computed field is the same, bit for bit, whatever `columns` says).
    ///
    /// # Errors
    /// A message naming the invalid input (`wi`, `wo`, the footprint).
    pub fn eval_row(
        &self,
        scratch: &mut QueryScratch,
        row: &EvalRow,
        columns: EvalColumns,
    ) -> Result<EvalAnswer, String> {
        let wi = direction(row.wi, "wi")?;
        let wo = direction(row.wo, "wo")?;
        let uv = vector2(row.uv, "uv")?;
        let duv_dx = edge(row.duv_dx, "duv_dx")?;
        let duv_dy = edge(row.duv_dy, "duv_dy")?;
        let footprint =
            Footprint::new(uv, duv_dx, duv_dy).map_err(|e| format!("footprint: {e}"))?;
        let bxdf = self.brdf.at(&footprint, scratch);
        let e = bxdf.evaluate(wi, wo);
        Ok(EvalAnswer {
            count: e.count,
            expected_count: if columns.expected_count {
                bxdf.expected_count(wi, wo)
            } else {
                f64::NAN
            },
            d_hat: e.d_hat.x,
            f_hat: e.f_hat,
            f_smooth: if columns.f_smooth {
                self.brdf.smooth_at(wi, wo, footprint.center())
            } else {
                DVec3::NAN
            },
            nodes_visited: e.nodes_visited,
            negligible_bound: e.negligible,
        })
    }

    /// [`EvalMaterial::eval_row`] of many rows in parallel, at a renderer's speed
    /// ([`crate::batch::answer_rows`]: per-thread scratches kept across calls, rows dispatched
    /// by footprint locality), answered in input order and bit for bit as one row at a time.
    /// Rows not answered because `cancelled` was set are `None`.
    pub fn eval_rows(
        &self,
        rows: &[EvalRow],
        columns: EvalColumns,
        cancelled: &AtomicBool,
    ) -> Vec<Option<Result<EvalAnswer, String>>> {
        answer_rows(rows, EvalRow::locality_key, cancelled, |scratch, row| {
            self.eval_row(scratch, row, columns)
        })
    }

    /// The `sample` request with the glint sampler's four uniform numbers (see
    /// [`uniforms_from_three`] for the three-number form): `None` when no direction is sampled.
    /// A material with maps samples, and weighs with its smooth limit, at texture position
    /// `uv` (without `uv`, by its levels' shares, and unmapped smooth weights).
    ///
    /// # Errors
    /// A message naming the invalid input (`wi`, `u`, `uv`).
    pub fn sample(
        &self,
        wi: [f64; 3],
        u: [f64; 4],
        uv: Option<[f64; 2]>,
    ) -> Result<Option<SampleAnswer>, String> {
        let wi = direction(wi, "wi")?;
        check_uniforms(&u)?;
        let uv = uv.map(|uv| vector2(uv, "uv")).transpose()?;
        let sampled = self.brdf.sample_smooth(wi, u, uv);
        Ok(sampled.map(|s| SampleAnswer {
            wo: s.wo,
            pdf: s.pdf,
            weight: s.weight,
        }))
    }

    /// The `pdf` request: the glint sampler's density (at texture position `uv` for a material
    /// with maps, as [`EvalMaterial::sample`]).
    ///
    /// # Errors
    /// A message naming the invalid direction or `uv`.
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3], uv: Option<[f64; 2]>) -> Result<f64, String> {
        let (wi, wo) = (direction(wi, "wi")?, direction(wo, "wo")?);
        Ok(match uv {
            Some(uv) => self.brdf.sampling_pdf_at(wi, wo, vector2(uv, "uv")?),
            None => self.brdf.sampling_pdf(wi, wo),
        })
    }
}

/// A direction as [`glint_brdf::frame::given_direction`] takes it (the C API's rule too);
/// zero and non-finite vectors are rejected.
fn direction(v: [f64; 3], name: &str) -> Result<DVec3, String> {
    let v = DVec3::from_array(v);
    if !v.is_finite() {
        return Err(format!("{name} must hold finite numbers, not {v}"));
    }
    glint_brdf::frame::given_direction(v).ok_or_else(|| format!("{name} has zero length"))
}

fn vector2(v: [f64; 2], name: &str) -> Result<DVec2, String> {
    let v = DVec2::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{name} must hold finite numbers, not {v}"))
    }
}

/// A footprint edge: finite, each component within ±[`Footprint::MAX_EDGE`] (the footprint's
/// area and count stay finite).
fn edge(v: [f64; 2], name: &str) -> Result<DVec2, String> {
    let v = vector2(v, name)?;
    if v.abs().max_element() > Footprint::MAX_EDGE {
        return Err(format!(
            "{name} must hold numbers within ±{:e}, not [{:?}, {:?}]",
            Footprint::MAX_EDGE,
            v.x,
            v.y
        ));
    }
    Ok(v)
}

fn check_uniforms(u: &[f64]) -> Result<(), String> {
    if u.iter().any(|x| !(0.0..1.0).contains(x)) {
        return Err("`u` must hold numbers in [0, 1)".to_owned());
    }
    Ok(())
}

/// The four uniform numbers of the three-number form `[u0, u1, u2]` of a `sample` request
/// (the form `eval` accepted first, kept so that such requests keep their meaning): u2's odd
/// and even bits give the cone's two numbers ([`split_uniform`]).
///
/// # Errors
/// When a number is outside [0, 1).
pub fn uniforms_from_three(u: [f64; 3]) -> Result<[f64; 4], String> {
    check_uniforms(&u)?;
    let [c0, c1] = split_uniform(u[2]);
    Ok([u[0], u[1], c0, c1])
}

/// Two uniforms from one: the odd and the even bits of its 52-bit mantissa fraction, bit
/// 2k + 1 being the more significant of each pair (so the first carries the coarse half).
#[must_use]
pub fn split_uniform(u: f64) -> [f64; 2] {
    let bits = (u.clamp(0.0, 1.0 - f64::EPSILON) * (1u64 << 52) as f64) as u64;
    let (mut odd, mut even) = (0u64, 0u64);
    for k in 0..26 {
        odd |= ((bits >> (2 * k + 1)) & 1) << k;
        even |= ((bits >> (2 * k)) & 1) << k;
    }
    let scale = 1.0 / (1u64 << 26) as f64;
    [odd as f64 * scale, even as f64 * scale]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_uniform_gives_two_uniforms() {
        let [a, b] = split_uniform(0.75);
        assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
        // 0.75 = 0b11 followed by zeros: the two coarsest bits go one to each half.
        assert_eq!([a, b], [0.5, 0.5]);
        // 0.625 = 0b101: bits 51 and 49, both odd-positioned, go to the first number.
        assert_eq!(split_uniform(0.625), [0.75, 0.0]);
    }

    /// Huge but finite components are a valid direction (their squared length overflows).
    #[test]
    fn huge_directions_are_directions() {
        let d = direction([1e200, 0.0, 1e200], "wi").unwrap();
        assert!((d - DVec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-15);
        assert!(
            direction([0.0; 3], "wi")
                .unwrap_err()
                .contains("zero length")
        );
        assert!(
            direction([f64::NAN, 0.0, 1.0], "wo")
                .unwrap_err()
                .contains("wo must hold finite")
        );
    }
}
