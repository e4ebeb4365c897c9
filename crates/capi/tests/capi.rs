//! Every function of the C API called through its C signature from Rust: answers bit for bit
//! equal to glint-brdf's own, the pinned first case of `tests/tests/stability.rs`, NULL
//! pointers, invalid parameters and arguments with messages that name them, and the threading
//! contract (one material shared, one scratch per thread).
// Calling the C functions from Rust is `unsafe`; each call passes live, valid pointers (or
// NULL on purpose).
#![allow(unsafe_code)]

use std::ffi::CStr;
use std::ptr;

use glint::{
    GlintDense, GlintDistribution, GlintEvaluation, GlintFootprint, GlintFresnel, GlintMapFilter,
    GlintMaterial, GlintMaterialParams, GlintMultinomial, GlintSample, GlintScratch, GlintStatus,
    glint_eval, glint_eval_batch, glint_eval_smooth, glint_eval_smooth_at, glint_expected_count,
    glint_last_error, glint_material_free, glint_material_new, glint_material_params_default,
    glint_pdf, glint_pdf_at, glint_sample, glint_scratch_free, glint_scratch_new, glint_version,
};
use glint_brdf::{
    Bxdf, BxdfSample, DVec2, DVec3, DenseCounts, DiscreteBrdf, DistributionKind, Footprint,
    Fresnel, GlintParameters, Microfacet, MultinomialMode, QueryScratch,
};

use GlintStatus::{GLINT_INVALID_ARGUMENT, GLINT_INVALID_PARAMETER, GLINT_NULL_POINTER, GLINT_OK};

/// (sin θ cos φ, sin θ sin φ, cos θ), as in glint-tests.
fn direction(theta: f64, phi: f64) -> [f64; 3] {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// The calling thread's last message.
fn last_error() -> String {
    // SAFETY: never NULL, NUL-terminated, valid until this thread's next call.
    unsafe { CStr::from_ptr(glint_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

fn default_params() -> GlintMaterialParams {
    let mut params = GlintMaterialParams::default();
    // SAFETY: a writable struct.
    assert_eq!(
        unsafe { glint_material_params_default(&mut params) },
        GLINT_OK
    );
    params
}

/// A material and a scratch from the C API, freed on drop.
struct Handles {
    material: *mut GlintMaterial,
    scratch: *mut GlintScratch,
}

impl Handles {
    fn new(params: &GlintMaterialParams) -> Self {
        let (mut material, mut scratch) = (ptr::null_mut(), ptr::null_mut());
        // SAFETY: valid pointers to a struct and to handle variables.
        unsafe {
            assert_eq!(glint_material_new(params, &mut material), GLINT_OK);
            assert_eq!(glint_scratch_new(&mut scratch), GLINT_OK);
        }
        assert!(!material.is_null() && !scratch.is_null());
        Self { material, scratch }
    }

    fn eval(&self, footprint: &GlintFootprint, wi: [f64; 3], wo: [f64; 3]) -> GlintEvaluation {
        let mut e = empty_evaluation();
        // SAFETY: live handles, this thread's scratch, readable arrays, a writable result.
        let status = unsafe {
            glint_eval(
                self.material,
                self.scratch,
                footprint,
                wi.as_ptr(),
                wo.as_ptr(),
                &mut e,
            )
        };
        assert_eq!(status, GLINT_OK, "{}", last_error());
        e
    }

    fn sample(&self, footprint: Option<&GlintFootprint>, wi: [f64; 3], u: [f64; 4]) -> GlintSample {
        let mut s = empty_sample();
        let footprint = footprint.map_or(ptr::null(), ptr::from_ref);
        // SAFETY: as in `eval`; the footprint may be NULL.
        let status = unsafe {
            glint_sample(
                self.material,
                self.scratch,
                footprint,
                wi.as_ptr(),
                u.as_ptr(),
                &mut s,
            )
        };
        assert_eq!(status, GLINT_OK, "{}", last_error());
        s
    }
}

impl Drop for Handles {
    fn drop(&mut self) {
        // SAFETY: handles from `new`, freed once.
        unsafe {
            assert_eq!(glint_material_free(self.material), GLINT_OK);
            assert_eq!(glint_scratch_free(self.scratch), GLINT_OK);
        }
    }
}

fn empty_evaluation() -> GlintEvaluation {
    GlintEvaluation {
        f_hat: [f64::NAN; 3],
        d_hat: [f64::NAN; 3],
        count: f64::NAN,
        nodes_visited: u32::MAX,
        nodes_overlapping: u32::MAX,
        skipped_as_negligible: -1,
        negligible_bound: f64::NAN,
    }
}

fn empty_sample() -> GlintSample {
    GlintSample {
        wo: [f64::NAN; 3],
        pdf: f64::NAN,
        weight: [f64::NAN; 3],
        valid: -1,
        smooth_weight: [f64::NAN; 3],
        footprint_weight: [f64::NAN; 3],
    }
}

/// What `glint_sample` writes when it draws no sample.
fn empty_answer_of_no_sample() -> GlintSample {
    GlintSample {
        wo: [0.0; 3],
        pdf: 0.0,
        weight: [0.0; 3],
        valid: 0,
        smooth_weight: [0.0; 3],
        footprint_weight: [0.0; 3],
    }
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// The first case of `tests/tests/stability.rs`: the paper's defaults with exact counts, a 0.03
/// footprint (the default dense mode answers it in the lattice's band with the tree: another
/// case there).
const PINNED_FOOTPRINT: GlintFootprint = GlintFootprint {
    uv: [0.3, 0.6],
    duv_dx: [0.03, 0.0],
    duv_dy: [0.0, 0.03],
};
const PINNED_COUNT: f64 = 6.0;
const PINNED_F_HAT: f64 = 7.506622317930054;

/// The defaults with exact counts, as the pinned query is taken.
fn exact_params() -> GlintMaterialParams {
    GlintMaterialParams {
        dense: GlintDense::GLINT_DENSE_EXACT as u32,
        ..default_params()
    }
}

fn pinned_directions() -> ([f64; 3], [f64; 3]) {
    (
        direction(0.4, 0.3),
        direction(0.36, 0.3 + std::f64::consts::PI),
    )
}

#[test]
fn the_pinned_query_of_the_stability_test() {
    let handles = Handles::new(&exact_params());
    let (wi, wo) = pinned_directions();
    let e = handles.eval(&PINNED_FOOTPRINT, wi, wo);
    assert_eq!(e.count, PINNED_COUNT);
    for f in e.f_hat {
        assert!((f - PINNED_F_HAT).abs() <= 1e-12 * PINNED_F_HAT, "{f}");
    }
    assert!(e.nodes_visited >= e.nodes_overlapping && e.nodes_overlapping > 0);
    assert_eq!((e.skipped_as_negligible, e.negligible_bound), (0, 0.0));
}

/// One material in both APIs.
struct Case {
    params: GlintMaterialParams,
    reference: GlintParameters,
    footprint: GlintFootprint,
    /// (θ, φ) of ω_i and ω_o.
    wi: (f64, f64),
    wo: (f64, f64),
}

fn cases() -> Vec<Case> {
    let defaults = default_params();
    let beckmann = Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).unwrap();
    let ggx = Microfacet::new(DistributionKind::Ggx, 0.2, 0.4).unwrap();
    let (eta, k) = ([0.2, 0.9, 1.1], [3.9, 2.4, 2.2]);
    vec![
        Case {
            params: defaults,
            reference: GlintParameters::new(beckmann),
            footprint: PINNED_FOOTPRINT,
            wi: (0.4, 0.3),
            wo: (0.36, 0.3 + std::f64::consts::PI),
        },
        Case {
            params: GlintMaterialParams {
                distribution: GlintDistribution::GLINT_GGX as u32,
                alpha_x: 0.2,
                alpha_y: 0.4,
                particles: 1e8,
                gamma_degrees: 3.0,
                epsilon: 0.0,
                seed: 5,
                fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
                conductor_eta: eta,
                conductor_k: k,
                ..defaults
            },
            reference: GlintParameters {
                particles: 100_000_000,
                gamma_radians: 3f64.to_radians(),
                epsilon: 0.0,
                seed: 5,
                fresnel: Fresnel::Conductor {
                    eta: DVec3::from_array(eta),
                    k: DVec3::from_array(k),
                },
                ..GlintParameters::new(ggx)
            },
            footprint: GlintFootprint {
                uv: [10.7, -3.2],
                duv_dx: [2e-3, 5e-4],
                duv_dy: [-3e-4, 1.5e-3],
            },
            wi: (0.7, 0.1),
            wo: (0.5, 3.0),
        },
        Case {
            params: GlintMaterialParams {
                particles: 1e5,
                fresnel: GlintFresnel::GLINT_FRESNEL_DIELECTRIC as u32,
                dielectric_eta: 1.5,
                multinomial: GlintMultinomial::GLINT_MULTINOMIAL_NORMAL as u32,
                pdf_points: 16,
                expected_footprint_area: 1e-4,
                ..defaults
            },
            reference: GlintParameters {
                particles: 100_000,
                fresnel: Fresnel::Dielectric { eta: 1.5 },
                multinomial: MultinomialMode::Normal,
                pdf_points: 16,
                expected_footprint_area: 1e-4,
                ..GlintParameters::new(beckmann)
            },
            footprint: GlintFootprint {
                uv: [0.5, 0.5],
                duv_dx: [0.1, 0.0],
                duv_dy: [0.0, 0.1],
            },
            wi: (0.2, 0.0),
            wo: (0.2, 3.0),
        },
        Case {
            // The lattice's band at N = 10⁹, where its tree samples nodes of twice the query's
            // width (`a_lattice_node_scale_reaches_its_tree` shows the scale changes the count).
            params: lattice_band_params(2.0),
            reference: GlintParameters {
                particles: 1_000_000_000,
                dense: DenseCounts::Lattice { node_scale: 2.0 },
                ..GlintParameters::new(beckmann)
            },
            footprint: LATTICE_BAND_FOOTPRINT,
            wi: LATTICE_BAND_WI,
            wo: LATTICE_BAND_WO,
        },
        Case {
            // A query far from the lobe on a tiny footprint: skipped as negligible.
            params: GlintMaterialParams {
                negligible_count: 1e-3,
                ..defaults
            },
            reference: GlintParameters {
                negligible_count: 1e-3,
                ..GlintParameters::new(beckmann)
            },
            footprint: GlintFootprint {
                uv: [0.3, 0.3],
                duv_dx: [1e-5, 0.0],
                duv_dy: [0.0, 1e-5],
            },
            wi: (1.2, 0.0),
            wo: (0.2, 0.0),
        },
    ]
}

/// A query of the lattice's band at N = 10⁹ near the highlight (λ = 4.5: the tree's count and
/// the lattice's blended).
const LATTICE_BAND_FOOTPRINT: GlintFootprint = GlintFootprint {
    uv: [0.41, 0.27],
    duv_dx: [8.4e-4, 1.4e-4],
    duv_dy: [-7e-5, 6.3e-4],
};
const LATTICE_BAND_WI: (f64, f64) = (0.5, 0.2);
const LATTICE_BAND_WO: (f64, f64) = (0.47, 0.2 + std::f64::consts::PI);

/// The defaults at N = 10⁹ under the lattice, its tree sampling nodes of `node_scale` widths.
fn lattice_band_params(node_scale: f64) -> GlintMaterialParams {
    GlintMaterialParams {
        particles: 1e9,
        dense: GlintDense::GLINT_DENSE_LATTICE as u32,
        dense_node_scale: node_scale,
        ..default_params()
    }
}

/// `dense_node_scale` reaches the tree that answers the lattice's band: the band case of
/// `cases()` changes its count with the scale, so its bit-for-bit check covers the field.
#[test]
fn a_lattice_node_scale_reaches_its_tree() {
    let count = |node_scale: f64| {
        let handles = Handles::new(&lattice_band_params(node_scale));
        let (wi, wo) = (
            direction(LATTICE_BAND_WI.0, LATTICE_BAND_WI.1),
            direction(LATTICE_BAND_WO.0, LATTICE_BAND_WO.1),
        );
        handles.eval(&LATTICE_BAND_FOOTPRINT, wi, wo).count
    };
    let (one, two) = (count(1.0), count(2.0));
    assert!(one > 0.0 && two > 0.0 && one != two, "{one} and {two}");
}

#[test]
fn answers_are_glint_brdf_answers_bit_for_bit() {
    let mut reference_scratch = QueryScratch::new();
    let (mut skipped, mut drawn) = (0, 0);
    for case in cases() {
        let handles = Handles::new(&case.params);
        let brdf = DiscreteBrdf::new(case.reference).unwrap();
        let f = case.footprint;
        let footprint = Footprint::new(
            DVec2::from_array(f.uv),
            DVec2::from_array(f.duv_dx),
            DVec2::from_array(f.duv_dy),
        )
        .unwrap();
        let (wi, wo) = (
            direction(case.wi.0, case.wi.1),
            direction(case.wo.0, case.wo.1),
        );
        // Unit vectors (to rounding) are passed to glint-brdf as they are.
        let (wi_unit, wo_unit) = (DVec3::from_array(wi), DVec3::from_array(wo));
        let bxdf = brdf.at(&footprint, &mut reference_scratch);

        let e = handles.eval(&f, wi, wo);
        let expected = bxdf.evaluate(wi_unit, wo_unit);
        assert_eq!(bits(&e.f_hat), bits(&expected.f_hat.to_array()));
        assert_eq!(bits(&e.d_hat), bits(&expected.d_hat.to_array()));
        assert_eq!(e.count.to_bits(), expected.count.to_bits());
        assert_eq!(e.nodes_visited, expected.nodes_visited);
        assert_eq!(e.nodes_overlapping, expected.nodes_overlapping);
        assert_eq!(
            e.skipped_as_negligible,
            i32::from(expected.negligible.is_some())
        );
        assert_eq!(e.negligible_bound, expected.negligible.unwrap_or(0.0));
        skipped += e.skipped_as_negligible;

        let mut count = f64::NAN;
        // SAFETY: live handles, readable arrays, a writable double.
        let status = unsafe {
            glint_expected_count(
                handles.material,
                handles.scratch,
                &f,
                wi.as_ptr(),
                wo.as_ptr(),
                &mut count,
            )
        };
        assert_eq!(status, GLINT_OK);
        assert_eq!(
            count.to_bits(),
            bxdf.expected_count(wi_unit, wo_unit).to_bits()
        );

        let mut smooth = [f64::NAN; 3];
        // SAFETY: a live material, readable arrays, 3 writable doubles.
        let status = unsafe {
            glint_eval_smooth(
                handles.material,
                wi.as_ptr(),
                wo.as_ptr(),
                smooth.as_mut_ptr(),
            )
        };
        assert_eq!(status, GLINT_OK);
        assert_eq!(
            bits(&smooth),
            bits(&brdf.smooth().eval(wi_unit, wo_unit).to_array())
        );

        for u in [
            [0.3, 0.6, 0.2, 0.9],
            [0.01, 0.99, 0.5, 0.5],
            [0.7, 0.2, 0.0, 0.3],
        ] {
            let glint = handles.sample(Some(&f), wi, u);
            let smooth = handles.sample(None, wi, u);
            let expected_glint = bxdf.sample(wi_unit, u);
            let expected_smooth = brdf.sample_direction(wi_unit, u).and_then(|wo| {
                BxdfSample::weighted(
                    wo,
                    brdf.smooth().eval(wi_unit, wo),
                    brdf.sampling_pdf(wi_unit, wo),
                )
            });
            // Both weights under their own names: f̂'s with the footprint, the smooth one's
            // always; the deprecated `weight` is the first with a footprint, else the second.
            if let (Some(g), Some(s)) = (expected_glint, expected_smooth) {
                assert_eq!(bits(&glint.footprint_weight), bits(&g.weight.to_array()));
                assert_eq!(bits(&glint.smooth_weight), bits(&s.weight.to_array()));
                assert_eq!(bits(&smooth.smooth_weight), bits(&s.weight.to_array()));
                assert_eq!(bits(&smooth.footprint_weight), bits(&[0.0; 3]));
            }
            for (got, expected) in [(glint, expected_glint), (smooth, expected_smooth)] {
                let Some(expected) = expected else {
                    assert_eq!(got, empty_answer_of_no_sample());
                    continue;
                };
                drawn += 1;
                assert_eq!(got.valid, 1);
                assert_eq!(bits(&got.wo), bits(&expected.wo.to_array()));
                assert_eq!(got.pdf.to_bits(), expected.pdf.to_bits());
                assert_eq!(bits(&got.weight), bits(&expected.weight.to_array()));
                let mut pdf = f64::NAN;
                // SAFETY: a live material, readable arrays, a writable double.
                let status =
                    unsafe { glint_pdf(handles.material, wi.as_ptr(), got.wo.as_ptr(), &mut pdf) };
                assert_eq!(status, GLINT_OK);
                assert_eq!(
                    pdf.to_bits(),
                    got.pdf.to_bits(),
                    "glint_pdf gives the sample's pdf"
                );
            }
        }
    }
    assert_eq!(
        skipped, 1,
        "the negligible case is skipped, the others traversed"
    );
    assert!(drawn >= 25, "only {drawn} of 30 draws gave a sample");
}

#[test]
fn directions_need_not_have_unit_length() {
    // Exact counts are whole and equal; the lattice's band (the defaults here) blends real
    // counts, equal to rounding (a direction scaled and normalized moves by an ulp).
    for (params, tolerance) in [(exact_params(), 0.0), (default_params(), 1e-12)] {
        let handles = Handles::new(&params);
        let (wi, wo) = pinned_directions();
        let unit = handles.eval(&PINNED_FOOTPRINT, wi, wo);
        assert!(unit.count > 0.0);
        for scale in [3.0, 1e-200, 1e200] {
            let scaled = |v: [f64; 3]| v.map(|x| x * scale);
            let e = handles.eval(&PINNED_FOOTPRINT, scaled(wi), scaled(wo));
            assert!((e.count - unit.count).abs() <= tolerance * unit.count);
            assert!((e.f_hat[0] - unit.f_hat[0]).abs() <= 1e-12 * unit.f_hat[0]);
        }
    }
}

#[test]
fn below_the_horizon_gives_zeros_and_no_sample() {
    let handles = Handles::new(&default_params());
    let below = [0.3, 0.0, -0.9];
    let e = handles.eval(&PINNED_FOOTPRINT, below, [0.0, 0.0, 1.0]);
    assert_eq!((e.f_hat, e.count, e.nodes_visited), ([0.0; 3], 0.0, 0));
    for footprint in [Some(&PINNED_FOOTPRINT), None] {
        let s = handles.sample(footprint, below, [0.3, 0.6, 0.2, 0.9]);
        assert_eq!(s, empty_answer_of_no_sample());
    }
}

/// Rust's defaults, except the negligible-query test: on at 10⁻¹² as in `eval`, Python and
/// glint-tracer.
#[test]
fn defaults_are_glint_parameters_new_with_evals_negligible_count() {
    let p = default_params();
    assert_eq!(p.distribution, GlintDistribution::GLINT_BECKMANN as u32);
    assert_eq!((p.alpha_x, p.alpha_y, p.particles), (0.1, 0.1, 1e6));
    assert_eq!((p.gamma_degrees, p.epsilon, p.seed), (1.0, 0.1, 0));
    assert_eq!(
        (p.dense, p.dense_node_scale),
        (GlintDense::GLINT_DENSE_LATTICE as u32, 1.0)
    );
    assert_eq!(
        p.map_filter,
        GlintMapFilter::GLINT_MAP_FILTER_NEAREST as u32
    );
    assert_eq!(p.fresnel, GlintFresnel::GLINT_FRESNEL_NONE as u32);
    assert_eq!(
        p.multinomial,
        GlintMultinomial::GLINT_MULTINOMIAL_EXACT as u32
    );
    assert_eq!((p.expected_footprint_area, p.pdf_points), (1e-6, 64));
    assert_eq!(p.negligible_count, 1e-12);
}

#[test]
fn invalid_parameters_are_named() {
    let defaults = default_params();
    let bad_density = [1.0, 1.5, 0.0, 0.2];
    let bad_alpha = [0.1, 0.1, 0.1, 0.0];
    let bad_tint = [0.5; 12].map(|x| x * 3.0);
    let cases: Vec<(GlintMaterialParams, &str)> = vec![
        (
            GlintMaterialParams {
                dense: 7,
                ..defaults
            },
            "dense",
        ),
        (
            GlintMaterialParams {
                dense_node_scale: 0.0,
                ..defaults
            },
            "dense_node_scale",
        ),
        (
            GlintMaterialParams {
                map_filter: 2,
                ..defaults
            },
            "map_filter = 2 is invalid: use GLINT_MAP_FILTER_NEAREST or GLINT_MAP_FILTER_BILINEAR",
        ),
        (
            GlintMaterialParams {
                density_map: bad_density.as_ptr(),
                density_map_width: 2,
                density_map_height: 2,
                ..defaults
            },
            "density_map: texel (column 1, row 0) is 1.5",
        ),
        (
            GlintMaterialParams {
                alpha_map: bad_alpha.as_ptr(),
                alpha_map_width: 2,
                alpha_map_height: 2,
                ..defaults
            },
            "alpha_map: texel (column 1, row 1) is 0.0",
        ),
        (
            GlintMaterialParams {
                tint_map: bad_tint.as_ptr(),
                tint_map_width: 2,
                tint_map_height: 2,
                ..defaults
            },
            "tint_map: texel (column 0, row 0) is 1.5",
        ),
        (
            GlintMaterialParams {
                density_map_width: 4,
                density_map_height: 4,
                ..defaults
            },
            "density_map is NULL with a size of 4 x 4",
        ),
        (
            GlintMaterialParams {
                alpha_map: bad_alpha.as_ptr(),
                alpha_map_width: 1 << 15,
                alpha_map_height: 1 << 14,
                ..defaults
            },
            "alpha_map is 32768 x 16384 texels",
        ),
        (
            GlintMaterialParams {
                roughness_levels: 0,
                ..defaults
            },
            "roughness_levels",
        ),
        (
            GlintMaterialParams {
                distribution: 7,
                ..defaults
            },
            "distribution = 7",
        ),
        (
            GlintMaterialParams {
                alpha_x: 0.0,
                ..defaults
            },
            "alpha_x: roughness alpha = 0",
        ),
        (
            GlintMaterialParams {
                alpha_y: f64::NAN,
                ..defaults
            },
            "alpha_y: roughness alpha = NaN",
        ),
        (
            GlintMaterialParams {
                particles: 0.5,
                ..defaults
            },
            "particles = 0.5",
        ),
        (
            GlintMaterialParams {
                particles: 2f64.powi(53) + 2.0,
                ..defaults
            },
            "particles =",
        ),
        (
            GlintMaterialParams {
                particles: f64::INFINITY,
                ..defaults
            },
            "particles = inf",
        ),
        (
            GlintMaterialParams {
                gamma_degrees: 90.0,
                ..defaults
            },
            "gamma_degrees: cone radius gamma",
        ),
        (
            GlintMaterialParams {
                gamma_degrees: 0.0,
                ..defaults
            },
            "gamma_degrees: cone radius gamma",
        ),
        (
            GlintMaterialParams {
                epsilon: -1.0,
                ..defaults
            },
            "epsilon: ",
        ),
        (
            GlintMaterialParams {
                fresnel: 9,
                ..defaults
            },
            "fresnel = 9",
        ),
        (
            GlintMaterialParams {
                fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
                conductor_eta: [1.0, -1.0, 1.0],
                ..defaults
            },
            "conductor_eta: Fresnel eta = -1.0",
        ),
        (
            GlintMaterialParams {
                fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
                conductor_eta: [1e300; 3],
                conductor_k: [1e300; 3],
                ..defaults
            },
            "conductor_eta: Fresnel eta = 1e300 is invalid: eta must be in [1e-3, 1e3]",
        ),
        (
            GlintMaterialParams {
                fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
                conductor_k: [0.0, 0.0, 1001.0],
                ..defaults
            },
            "conductor_k: Fresnel k = 1001.0",
        ),
        (
            GlintMaterialParams {
                gamma_degrees: 1e-5,
                ..defaults
            },
            "gamma_degrees: ",
        ),
        (
            GlintMaterialParams {
                epsilon: 1.5,
                ..defaults
            },
            "epsilon: ",
        ),
        (
            GlintMaterialParams {
                fresnel: GlintFresnel::GLINT_FRESNEL_DIELECTRIC as u32,
                dielectric_eta: 0.0,
                ..defaults
            },
            "dielectric_eta: Fresnel",
        ),
        (
            GlintMaterialParams {
                multinomial: 5,
                ..defaults
            },
            "multinomial = 5",
        ),
        (
            GlintMaterialParams {
                pdf_quadrature: 2,
                ..defaults
            },
            "pdf_quadrature = 2",
        ),
        (
            GlintMaterialParams {
                expected_footprint_area: 0.0,
                ..defaults
            },
            "expected_footprint_area: ",
        ),
        (
            GlintMaterialParams {
                pdf_points: 0,
                ..defaults
            },
            "pdf_points: ",
        ),
        (
            GlintMaterialParams {
                pdf_points: 5000,
                ..defaults
            },
            "pdf_points: ",
        ),
        (
            GlintMaterialParams {
                negligible_count: -1.0,
                ..defaults
            },
            "negligible_count: ",
        ),
    ];
    for (params, expected) in cases {
        // A stale handle value: a failed call must overwrite it with NULL.
        let mut material = ptr::NonNull::<GlintMaterial>::dangling().as_ptr();
        // SAFETY: a readable struct and a writable handle variable.
        let status = unsafe { glint_material_new(&params, &mut material) };
        assert_eq!(status, GLINT_INVALID_PARAMETER, "{expected}");
        assert!(material.is_null());
        let message = last_error();
        assert!(
            message.starts_with(&format!("glint_material_new: {expected}")),
            "{message:?} should start with {expected:?}"
        );
    }
}

#[test]
fn invalid_arguments_are_named() {
    let handles = Handles::new(&default_params());
    let (wi, wo) = pinned_directions();
    let mut e = empty_evaluation();
    let eval = |footprint: &GlintFootprint, wi: [f64; 3], wo: [f64; 3], e: &mut GlintEvaluation| {
        // SAFETY: live handles, readable arrays, a writable result.
        let status = unsafe {
            glint_eval(
                handles.material,
                handles.scratch,
                footprint,
                wi.as_ptr(),
                wo.as_ptr(),
                e,
            )
        };
        (status, last_error())
    };
    let nan = f64::NAN;
    let (status, message) = eval(&PINNED_FOOTPRINT, [nan, 0.0, 1.0], wo, &mut e);
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    assert_eq!(message, "glint_eval: `wi` = [NaN, 0, 1] is not finite");
    let (status, message) = eval(&PINNED_FOOTPRINT, wi, [0.0, -0.0, 0.0], &mut e);
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    assert_eq!(
        message,
        "glint_eval: `wo` is the zero vector, not a direction"
    );
    let infinite = GlintFootprint {
        duv_dx: [f64::INFINITY, 0.0],
        ..PINNED_FOOTPRINT
    };
    let (status, message) = eval(&infinite, wi, wo, &mut e);
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    assert!(
        message.starts_with("glint_eval: `footprint`: "),
        "{message}"
    );
    assert_eq!(
        e.count.to_bits(),
        f64::NAN.to_bits(),
        "nothing written on failure"
    );
    // A footprint whose area (or area times N) would overflow is refused, naming it.
    for huge in [1e154, 1e300, 1.0000001e15] {
        let footprint = GlintFootprint {
            duv_dx: [huge, 0.0],
            duv_dy: [0.0, huge],
            ..PINNED_FOOTPRINT
        };
        let (status, message) = eval(&footprint, wi, wo, &mut e);
        assert_eq!(status, GLINT_INVALID_ARGUMENT);
        assert!(
            message.starts_with("glint_eval: `footprint`: footprint edge component")
                && message.contains("±1e15"),
            "{message}"
        );
    }

    let mut s = empty_sample();
    for (u, name) in [
        ([0.3, 1.0, 0.2, 0.9], "`u[1]` = 1 is outside [0, 1)"),
        ([0.3, 0.6, -0.1, 0.9], "`u[2]` = -0.1 is outside [0, 1)"),
        ([0.3, 0.6, 0.2, nan], "`u[3]` = NaN is outside [0, 1)"),
    ] {
        for footprint in [ptr::from_ref(&PINNED_FOOTPRINT), ptr::null()] {
            // SAFETY: live handles, readable arrays, a writable result.
            let status = unsafe {
                glint_sample(
                    handles.material,
                    handles.scratch,
                    footprint,
                    wi.as_ptr(),
                    u.as_ptr(),
                    &mut s,
                )
            };
            assert_eq!(status, GLINT_INVALID_ARGUMENT);
            assert_eq!(last_error(), format!("glint_sample: {name}"));
        }
    }
    let mut value = [0.0; 3];
    // SAFETY: a live material, readable arrays, writable doubles.
    unsafe {
        let zero = [0.0; 3];
        let status = glint_eval_smooth(
            handles.material,
            zero.as_ptr(),
            wo.as_ptr(),
            value.as_mut_ptr(),
        );
        assert_eq!(status, GLINT_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "glint_eval_smooth: `wi` is the zero vector, not a direction"
        );
        let status = glint_pdf(
            handles.material,
            wi.as_ptr(),
            [nan; 3].as_ptr(),
            value.as_mut_ptr(),
        );
        assert_eq!(status, GLINT_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "glint_pdf: `wo` = [NaN, NaN, NaN] is not finite"
        );
    }
    // A success clears the message.
    handles.eval(&PINNED_FOOTPRINT, wi, wo);
    assert_eq!(last_error(), "");
}

#[test]
fn null_pointers_are_named() {
    let handles = Handles::new(&default_params());
    let (m, s) = (handles.material.cast_const(), handles.scratch);
    let fp = ptr::from_ref(&PINNED_FOOTPRINT);
    let (wi, wo) = pinned_directions();
    let (wi, wo) = (wi.as_ptr(), wo.as_ptr());
    let u = [0.3, 0.6, 0.2, 0.9];
    let u = u.as_ptr();
    let (mut e, mut sample, mut x, mut f) = (empty_evaluation(), empty_sample(), 0.0, [0.0; 3]);
    let (e, sample, x, f) = (
        ptr::from_mut(&mut e),
        ptr::from_mut(&mut sample),
        ptr::from_mut(&mut x),
        f.as_mut_ptr(),
    );
    let null = ptr::null::<f64>();
    let null_mut = ptr::null_mut::<f64>();
    let mut out_material = ptr::null_mut();
    let params = default_params();
    // Checks one call's status and message (the arguments are evaluated first: the call).
    let check = |status: GlintStatus, function: &str, argument: &str| {
        assert_eq!(status, GLINT_NULL_POINTER, "{function}({argument} = NULL)");
        assert_eq!(last_error(), format!("{function}: `{argument}` is NULL"));
    };
    // SAFETY: every pointer is live and valid, or NULL on purpose.
    unsafe {
        check(
            glint_material_params_default(ptr::null_mut()),
            "glint_material_params_default",
            "params",
        );
        check(
            glint_material_new(ptr::null(), &mut out_material),
            "glint_material_new",
            "params",
        );
        check(
            glint_material_new(&params, ptr::null_mut()),
            "glint_material_new",
            "material",
        );
        check(
            glint_scratch_new(ptr::null_mut()),
            "glint_scratch_new",
            "scratch",
        );
        check(
            glint_eval(ptr::null(), s, fp, wi, wo, e),
            "glint_eval",
            "material",
        );
        check(
            glint_eval(m, ptr::null_mut(), fp, wi, wo, e),
            "glint_eval",
            "scratch",
        );
        check(
            glint_eval(m, s, ptr::null(), wi, wo, e),
            "glint_eval",
            "footprint",
        );
        check(glint_eval(m, s, fp, null, wo, e), "glint_eval", "wi");
        check(glint_eval(m, s, fp, wi, null, e), "glint_eval", "wo");
        check(
            glint_eval(m, s, fp, wi, wo, ptr::null_mut()),
            "glint_eval",
            "evaluation",
        );
        check(
            glint_expected_count(ptr::null(), s, fp, wi, wo, x),
            "glint_expected_count",
            "material",
        );
        check(
            glint_expected_count(m, ptr::null_mut(), fp, wi, wo, x),
            "glint_expected_count",
            "scratch",
        );
        check(
            glint_expected_count(m, s, ptr::null(), wi, wo, x),
            "glint_expected_count",
            "footprint",
        );
        check(
            glint_expected_count(m, s, fp, null, wo, x),
            "glint_expected_count",
            "wi",
        );
        check(
            glint_expected_count(m, s, fp, wi, null, x),
            "glint_expected_count",
            "wo",
        );
        check(
            glint_expected_count(m, s, fp, wi, wo, null_mut),
            "glint_expected_count",
            "count",
        );
        check(
            glint_eval_smooth(ptr::null(), wi, wo, f),
            "glint_eval_smooth",
            "material",
        );
        check(glint_eval_smooth(m, null, wo, f), "glint_eval_smooth", "wi");
        check(glint_eval_smooth(m, wi, null, f), "glint_eval_smooth", "wo");
        check(
            glint_eval_smooth(m, wi, wo, null_mut),
            "glint_eval_smooth",
            "f",
        );
        check(
            glint_sample(ptr::null(), s, fp, wi, u, sample),
            "glint_sample",
            "material",
        );
        check(
            glint_sample(m, ptr::null_mut(), fp, wi, u, sample),
            "glint_sample",
            "scratch",
        );
        check(
            glint_sample(m, s, fp, null, u, sample),
            "glint_sample",
            "wi",
        );
        check(
            glint_sample(m, s, fp, wi, null, sample),
            "glint_sample",
            "u",
        );
        check(
            glint_sample(m, s, fp, wi, u, ptr::null_mut()),
            "glint_sample",
            "sample",
        );
        check(glint_pdf(ptr::null(), wi, wo, x), "glint_pdf", "material");
        check(glint_pdf(m, null, wo, x), "glint_pdf", "wi");
        check(glint_pdf(m, wi, null, x), "glint_pdf", "wo");
        check(glint_pdf(m, wi, wo, null_mut), "glint_pdf", "pdf");
    }
    assert!(out_material.is_null());
    // A NULL footprint is allowed in `glint_sample`, and then so is a NULL scratch.
    // SAFETY: as above.
    let status = unsafe { glint_sample(m, ptr::null_mut(), ptr::null(), wi, u, sample) };
    assert_eq!(status, GLINT_OK);
    // Freeing NULL is a no-op.
    // SAFETY: NULL handles.
    unsafe {
        assert_eq!(glint_material_free(ptr::null_mut()), GLINT_OK);
        assert_eq!(glint_scratch_free(ptr::null_mut()), GLINT_OK);
    }
}

#[test]
fn one_material_shared_by_threads_each_with_its_scratch() {
    let handles = Handles::new(&default_params());
    let queries: Vec<([f64; 3], [f64; 3])> = (0..24)
        .map(|i| {
            let theta = 0.1 + 0.05 * f64::from(i);
            (
                direction(theta, 0.3),
                direction(theta * 0.9, 0.3 + std::f64::consts::PI),
            )
        })
        .collect();
    let serial: Vec<GlintEvaluation> = queries
        .iter()
        .map(|&(wi, wo)| handles.eval(&PINNED_FOOTPRINT, wi, wo))
        .collect();
    // Raw pointers are not `Send`; the address is.
    let material = handles.material as usize;
    let parallel: Vec<Vec<GlintEvaluation>> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..3)
            .map(|_| {
                let queries = &queries;
                scope.spawn(move || {
                    let mut scratch = ptr::null_mut();
                    // SAFETY: a writable handle variable.
                    assert_eq!(unsafe { glint_scratch_new(&mut scratch) }, GLINT_OK);
                    let results = queries
                        .iter()
                        .map(|(wi, wo)| {
                            let mut e = empty_evaluation();
                            // SAFETY: the shared material outlives the scope; this thread's
                            // own scratch; readable arrays, a writable result.
                            let status = unsafe {
                                glint_eval(
                                    material as *const GlintMaterial,
                                    scratch,
                                    &PINNED_FOOTPRINT,
                                    wi.as_ptr(),
                                    wo.as_ptr(),
                                    &mut e,
                                )
                            };
                            assert_eq!(status, GLINT_OK);
                            e
                        })
                        .collect();
                    // SAFETY: this thread's scratch, freed once.
                    assert_eq!(unsafe { glint_scratch_free(scratch) }, GLINT_OK);
                    results
                })
            })
            .collect();
        workers.into_iter().map(|w| w.join().unwrap()).collect()
    });
    for results in parallel {
        assert_eq!(results, serial);
    }
}

#[test]
fn messages_are_per_thread() {
    let params = GlintMaterialParams {
        gamma_degrees: 90.0,
        ..default_params()
    };
    let mut material = ptr::null_mut();
    // SAFETY: a readable struct and a writable handle variable.
    let status = unsafe { glint_material_new(&params, &mut material) };
    assert_eq!(status, GLINT_INVALID_PARAMETER);
    let here = last_error();
    assert!(here.starts_with("glint_material_new: gamma_degrees"));
    let there = std::thread::spawn(last_error).join().unwrap();
    assert_eq!(there, "", "another thread has no message");
    assert_eq!(last_error(), here);
}

#[test]
fn one_scratch_serves_every_material() {
    let a = Handles::new(&default_params());
    let b = Handles::new(&GlintMaterialParams {
        seed: 3,
        particles: 1e7,
        ..default_params()
    });
    let (wi, wo) = pinned_directions();
    let fresh_b = b.eval(&PINNED_FOOTPRINT, wi, wo);
    // `a`'s scratch, used by `a` first, then by `b`.
    a.eval(&PINNED_FOOTPRINT, wi, wo);
    let mut e = empty_evaluation();
    // SAFETY: live handles, readable arrays, a writable result.
    let status = unsafe {
        glint_eval(
            b.material,
            a.scratch,
            &PINNED_FOOTPRINT,
            wi.as_ptr(),
            wo.as_ptr(),
            &mut e,
        )
    };
    assert_eq!(status, GLINT_OK);
    assert_eq!(e, fresh_b);
}

#[test]
fn version_is_the_package_version() {
    // SAFETY: a static NUL-terminated string.
    let version = unsafe { CStr::from_ptr(glint_version()) };
    assert_eq!(version.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
}

/// The C API answers as glint-eval (and so `cargo xtask eval` and Python) does, bit for bit,
/// for the same input: directions of unit length to rounding (each side of 1 by a few ulps,
/// where normalizing again would move the last bits), far from unit, and the extremes of the
/// accepted ranges (η, k at their limits, a footprint edge at ±1e15).
#[test]
fn answers_are_glint_evals_bit_for_bit() {
    use glint_eval::{FresnelSpec, MapSpec, MapsSpec, MaterialSpec};
    // A material with every map (3 × 2 texels; 6 distinct α over K = 4 levels interpolate).
    let densities = [1.0, 0.5, 0.0, 0.25, 0.75, 1.0];
    let alphas = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5];
    let tints = [
        0.9, 0.5, 0.2, 0.1, 0.8, 0.3, 1.0, 1.0, 1.0, 0.4, 0.4, 0.9, 0.0, 0.6, 0.3, 0.7, 0.2, 0.5,
    ];
    let spec_map = |values: &[f64]| MapSpec {
        width: 3,
        height: 2,
        values: values.to_vec(),
    };
    let mapped = (
        GlintMaterialParams {
            density_map: densities.as_ptr(),
            density_map_width: 3,
            density_map_height: 2,
            alpha_map: alphas.as_ptr(),
            alpha_map_width: 3,
            alpha_map_height: 2,
            tint_map: tints.as_ptr(),
            tint_map_width: 3,
            tint_map_height: 2,
            roughness_levels: 4,
            particles: 1e8,
            ..default_params()
        },
        MaterialSpec {
            maps: MapsSpec {
                density_map: Some(spec_map(&densities)),
                alpha_map: Some(spec_map(&alphas)),
                tint_map: Some(spec_map(&tints)),
                roughness_levels: Some(4.0),
                map_filter: None,
            },
            ..MaterialSpec::new("beckmann", 0.1, 1e8, 1.0)
        },
    );
    // The same maps reconstructed bilinearly.
    let bilinear = (
        GlintMaterialParams {
            map_filter: GlintMapFilter::GLINT_MAP_FILTER_BILINEAR as u32,
            ..mapped.0
        },
        MaterialSpec {
            maps: MapsSpec {
                map_filter: Some("bilinear".to_owned()),
                ..mapped.1.maps.clone()
            },
            ..mapped.1.clone()
        },
    );
    let materials = [
        mapped,
        bilinear,
        (
            default_params(),
            MaterialSpec::new("beckmann", 0.1, 1e6, 1.0),
        ),
        (
            GlintMaterialParams {
                fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
                conductor_eta: [1e-3, 1.0, 1e3],
                conductor_k: [1e3, 0.0, 1e3],
                particles: 1e9,
                ..default_params()
            },
            MaterialSpec {
                fresnel: FresnelSpec::Conductor {
                    eta: [1e-3, 1.0, 1e3],
                    k: [1e3, 0.0, 1e3],
                },
                ..MaterialSpec::new("beckmann", 0.1, 1e9, 1.0)
            },
        ),
    ];
    let mut scratch = QueryScratch::new();
    // Lengths 1 + k·ε: a few roundings from unit, or far from it.
    let nudged = |v: [f64; 3], k: f64| v.map(|x| x * (1.0 + k * f64::EPSILON));
    let mut unchanged = 0;
    for (params, spec) in materials {
        let handles = Handles::new(&params);
        let material = spec.build().unwrap();
        for (i, theta) in [0.0, 0.3, 0.9, 1.4, 1.56].into_iter().enumerate() {
            let wi = direction(theta, 0.2 + f64::from(i as u32));
            let wo = direction(theta * 0.9, 3.3 + f64::from(i as u32));
            for k in [-2.0, -0.5, 0.0, 0.5, 1.0, 2.0, 1e12] {
                let (wi, wo) = (nudged(wi, k), nudged(wo, -k));
                for footprint in [
                    PINNED_FOOTPRINT,
                    GlintFootprint {
                        uv: [0.4, 0.2],
                        duv_dx: [1e15, 3.0],
                        duv_dy: [-2.0, 1e15],
                    },
                ] {
                    let c = handles.eval(&footprint, wi, wo);
                    let e = material
                        .eval(
                            &mut scratch,
                            wi,
                            wo,
                            footprint.uv,
                            footprint.duv_dx,
                            footprint.duv_dy,
                        )
                        .unwrap();
                    assert_eq!(bits(&c.f_hat), bits(&e.f_hat.to_array()), "{wi:?} {wo:?}");
                    assert_eq!(c.count.to_bits(), e.count.to_bits());
                    assert_eq!(c.d_hat[0].to_bits(), e.d_hat.to_bits());
                    assert!(
                        c.f_hat
                            .iter()
                            .chain([&c.count])
                            .all(|x| x.is_finite() && *x >= 0.0),
                        "{c:?}"
                    );
                    unchanged += usize::from(c.count > 0.0);
                }
                // With a footprint, a material with maps samples at its centre.
                let s = handles.sample(Some(&PINNED_FOOTPRINT), wi, [0.3, 0.6, 0.2, 0.9]);
                let e = material
                    .sample(wi, [0.3, 0.6, 0.2, 0.9], Some(PINNED_FOOTPRINT.uv))
                    .unwrap();
                match e {
                    Some(e) => {
                        assert_eq!(bits(&s.wo), bits(&e.wo.to_array()));
                        assert_eq!(s.pdf.to_bits(), e.pdf.to_bits());
                        assert_eq!(bits(&s.smooth_weight), bits(&e.weight.to_array()));
                    }
                    None => assert_eq!(s.valid, 0),
                }
                let s = handles.sample(None, wi, [0.3, 0.6, 0.2, 0.9]);
                let e = material.sample(wi, [0.3, 0.6, 0.2, 0.9], None).unwrap();
                match e {
                    Some(e) => {
                        assert_eq!(bits(&s.wo), bits(&e.wo.to_array()));
                        assert_eq!(s.pdf.to_bits(), e.pdf.to_bits());
                        assert_eq!(bits(&s.weight), bits(&e.weight.to_array()));
                    }
                    None => assert_eq!(s.valid, 0),
                }
                let mut pdf = f64::NAN;
                // SAFETY: a live material, readable arrays, a writable double.
                let status =
                    unsafe { glint_pdf(handles.material, wi.as_ptr(), wo.as_ptr(), &mut pdf) };
                assert_eq!(status, GLINT_OK);
                assert_eq!(pdf.to_bits(), material.pdf(wi, wo, None).unwrap().to_bits());
                let (mut pdf_at, mut smooth_at) = (f64::NAN, [f64::NAN; 3]);
                let uv = PINNED_FOOTPRINT.uv;
                // SAFETY: a live material, readable arrays, writable doubles.
                let statuses = unsafe {
                    [
                        glint_pdf_at(
                            handles.material,
                            wi.as_ptr(),
                            wo.as_ptr(),
                            uv.as_ptr(),
                            &mut pdf_at,
                        ),
                        glint_eval_smooth_at(
                            handles.material,
                            wi.as_ptr(),
                            wo.as_ptr(),
                            uv.as_ptr(),
                            smooth_at.as_mut_ptr(),
                        ),
                    ]
                };
                assert_eq!(statuses, [GLINT_OK; 2]);
                assert_eq!(
                    pdf_at.to_bits(),
                    material.pdf(wi, wo, Some(uv)).unwrap().to_bits()
                );
                let footprint = PINNED_FOOTPRINT;
                let e = material
                    .eval(&mut scratch, wi, wo, uv, footprint.duv_dx, footprint.duv_dy)
                    .unwrap();
                assert_eq!(bits(&smooth_at), bits(&e.f_smooth.to_array()));
            }
        }
    }
    assert!(unchanged > 0, "some queries find particles");
}

/// The ends of the ranges `GlintMaterialParams` documents are accepted (the invalid values
/// just beyond them are in `invalid_parameters_are_named`).
#[test]
fn documented_ranges_are_accepted_at_their_ends() {
    let defaults = default_params();
    let conductor = |eta: f64, k: f64| GlintMaterialParams {
        fresnel: GlintFresnel::GLINT_FRESNEL_CONDUCTOR as u32,
        conductor_eta: [eta; 3],
        conductor_k: [k; 3],
        ..defaults
    };
    for params in [
        GlintMaterialParams {
            gamma_degrees: 5.73e-5,
            ..defaults
        },
        GlintMaterialParams {
            gamma_degrees: 60.0,
            ..defaults
        },
        GlintMaterialParams {
            epsilon: 0.0,
            ..defaults
        },
        GlintMaterialParams {
            epsilon: 1.0,
            ..defaults
        },
        GlintMaterialParams {
            seed: u64::MAX,
            ..defaults
        },
        conductor(1e-3, 0.0),
        conductor(1e3, 1e3),
        GlintMaterialParams {
            fresnel: GlintFresnel::GLINT_FRESNEL_DIELECTRIC as u32,
            dielectric_eta: 1e3,
            ..defaults
        },
    ] {
        let handles = Handles::new(&params);
        let e = handles.eval(&PINNED_FOOTPRINT, [0.0, 0.0, 1.0], [0.1, 0.0, 0.99]);
        assert!(
            e.f_hat.iter().all(|f| f.is_finite() && *f >= 0.0),
            "{params:?}: {e:?}"
        );
    }
}

/// `glint_eval_batch` answers each row as `glint_eval` does, bit for bit, for any batch size
/// (one call, or pieces of odd sizes); a row `glint_eval` refuses gets its status and zeros, the
/// call returns that status naming the first such row, and the others are answered.
#[test]
fn batches_answer_as_glint_eval_row_by_row() {
    let params = GlintMaterialParams {
        particles: 1e8,
        negligible_count: 1e-12,
        ..default_params()
    };
    let handles = Handles::new(&params);
    let mut footprints = Vec::new();
    let (mut wi, mut wo) = (Vec::new(), Vec::new());
    for i in 0..900 {
        let x = f64::from(i % 30);
        let y = f64::from(i / 30);
        footprints.push(GlintFootprint {
            uv: [0.2 + 1e-3 * x, 0.7 + 1e-3 * y],
            duv_dx: [1e-3, 0.0],
            duv_dy: [0.0, 1e-3],
        });
        let theta = 0.2 + 0.02 * x;
        wi.extend(direction(theta, 0.1));
        wo.extend(direction(
            theta + 0.01 * f64::from(i % 7),
            0.1 + std::f64::consts::PI,
        ));
    }
    // Row 5 has a zero direction, row 600 a footprint that is not finite.
    wi[15..18].copy_from_slice(&[0.0; 3]);
    footprints[600].uv[0] = f64::NAN;
    let single: Vec<Option<GlintEvaluation>> = (0..footprints.len())
        .map(|i| {
            let mut e = empty_evaluation();
            // SAFETY: live handles, this thread's scratch, readable arrays, a writable result.
            let status = unsafe {
                glint_eval(
                    handles.material,
                    handles.scratch,
                    &footprints[i],
                    wi[3 * i..].as_ptr(),
                    wo[3 * i..].as_ptr(),
                    &mut e,
                )
            };
            (status == GLINT_OK).then_some(e)
        })
        .collect();
    assert_eq!(single.iter().filter(|e| e.is_none()).count(), 2);
    let batch = |range: std::ops::Range<usize>| {
        let n = range.len();
        let mut evaluations = vec![empty_evaluation(); n];
        let mut statuses = vec![GLINT_OK; n];
        // SAFETY: a live material; n footprints, 3n doubles each and n writable results.
        let status = unsafe {
            glint_eval_batch(
                handles.material,
                n,
                footprints[range.clone()].as_ptr(),
                wi[3 * range.start..].as_ptr(),
                wo[3 * range.start..].as_ptr(),
                evaluations.as_mut_ptr(),
                statuses.as_mut_ptr(),
            )
        };
        (status, last_error(), evaluations, statuses)
    };
    let (status, message, evaluations, statuses) = batch(0..footprints.len());
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    assert!(
        message.starts_with("glint_eval_batch: row 5: `wi`"),
        "{message}"
    );
    for (i, expected) in single.iter().enumerate() {
        match expected {
            Some(e) => {
                assert_eq!(statuses[i], GLINT_OK);
                assert_eq!(bits(&evaluations[i].f_hat), bits(&e.f_hat), "row {i}");
                assert_eq!(evaluations[i], *e, "row {i}");
            }
            None => {
                assert_eq!(statuses[i], GLINT_INVALID_ARGUMENT);
                assert_eq!(evaluations[i].count, 0.0);
                assert_eq!(evaluations[i].nodes_visited, 0);
            }
        }
    }
    let (status, message, evaluations, _) = batch(610..900);
    assert_eq!((status, message.as_str()), (GLINT_OK, ""));
    assert_eq!(
        evaluations,
        single[610..900]
            .iter()
            .map(|e| e.unwrap())
            .collect::<Vec<_>>()
    );
    // A batch of more rows than the call hands its pool at once (2^14) answers every row as
    // glint_eval, across the chunks' edges.
    let copies = 37;
    let long_footprints: Vec<GlintFootprint> = footprints.repeat(copies);
    let (long_wi, long_wo) = (wi.repeat(copies), wo.repeat(copies));
    let n = long_footprints.len();
    let mut evaluations = vec![empty_evaluation(); n];
    let mut statuses = vec![GLINT_OK; n];
    // SAFETY: a live material; n footprints, 3n doubles each and n writable results.
    let status = unsafe {
        glint_eval_batch(
            handles.material,
            n,
            long_footprints.as_ptr(),
            long_wi.as_ptr(),
            long_wo.as_ptr(),
            evaluations.as_mut_ptr(),
            statuses.as_mut_ptr(),
        )
    };
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    for (i, evaluation) in evaluations.iter().enumerate() {
        match single[i % footprints.len()] {
            Some(expected) => assert_eq!(*evaluation, expected, "row {i}"),
            None => assert_eq!(
                (statuses[i], evaluation.count),
                (GLINT_INVALID_ARGUMENT, 0.0)
            ),
        }
    }
    // An `n` no array can hold is refused before anything is read (it aborted the process on
    // allocating its row order).
    let huge = usize::MAX / std::mem::size_of::<GlintEvaluation>() + 1;
    // SAFETY: the call checks `n` against what memory can hold before reading any array.
    let status = unsafe {
        glint_eval_batch(
            handles.material,
            huge,
            footprints.as_ptr(),
            wi.as_ptr(),
            wo.as_ptr(),
            evaluations.as_mut_ptr(),
            statuses.as_mut_ptr(),
        )
    };
    assert_eq!(status, GLINT_INVALID_ARGUMENT);
    let message = last_error();
    assert!(message.contains("larger than memory can hold"), "{message}");
    // Nothing to do: NULL arrays are fine when n is 0; NULL with rows is named.
    // SAFETY: n = 0 reads and writes nothing; the material is live.
    let status = unsafe {
        glint_eval_batch(
            handles.material,
            0,
            ptr::null(),
            ptr::null(),
            ptr::null(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(status, GLINT_OK);
    // SAFETY: as above; the NULL is reported before anything is read.
    let status = unsafe {
        glint_eval_batch(
            handles.material,
            1,
            footprints.as_ptr(),
            ptr::null(),
            wo.as_ptr(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(status, GLINT_NULL_POINTER);
    assert_eq!(last_error(), "glint_eval_batch: `wi` is NULL");
}

/// Directions 1e-200 above the horizon (issue 64): `glint_eval_smooth` gave NaN for every
/// distribution, and `glint_pdf` NaN for GGX with γ = 60° and ω_i 1e-300 above it.
#[test]
fn near_horizon_directions_give_finite_answers() {
    for kind in DistributionKind::ALL {
        for gamma_degrees in [1.0, 60.0] {
            let handles = Handles::new(&GlintMaterialParams {
                distribution: kind.code(),
                alpha_x: 0.2,
                alpha_y: 0.2,
                gamma_degrees,
                ..default_params()
            });
            for (wi, wo) in [
                ([0.6, -0.8, 1e-200], [-0.6, 0.3, 1e-200]),
                ([0.6, -0.8, 1e-300], [-0.6, 0.3, 0.5]),
            ] {
                let mut smooth = [f64::NAN; 3];
                let mut pdf = f64::NAN;
                // SAFETY: a live material, readable arrays, writable doubles.
                let statuses = unsafe {
                    [
                        glint_eval_smooth(
                            handles.material,
                            wi.as_ptr(),
                            wo.as_ptr(),
                            smooth.as_mut_ptr(),
                        ),
                        glint_pdf(handles.material, wi.as_ptr(), wo.as_ptr(), &mut pdf),
                    ]
                };
                assert_eq!(statuses, [GLINT_OK, GLINT_OK]);
                assert!(
                    smooth.iter().all(|f| f.is_finite() && *f >= 0.0)
                        && pdf.is_finite()
                        && pdf >= 0.0,
                    "{kind}, γ = {gamma_degrees}°, {wi:?} {wo:?}: f = {smooth:?}, pdf = {pdf}"
                );
            }
        }
    }
}
