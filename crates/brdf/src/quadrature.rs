//! Gauss–Kronrod quadrature: the 15-point rule with its embedded 7-point Gauss rule, a
//! smoothed form for integrands with square-root edges, and the adaptive rule that halves the
//! piece with the largest error estimate. The slope-space pdf and the Λ of distributions
//! without a closed form use them.

/// The 15-point Gauss–Kronrod rule on [−1, 1]: nodes x ≥ 0 (each used at ±x) with their
/// Kronrod weights, and the weights of the embedded 7-point Gauss rule on the odd-indexed
/// nodes (the Gauss rule is exact to degree 13, the Kronrod rule to degree 23).
const KRONROD_NODES: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const KRONROD_WEIGHTS: [f64; 8] = [
    0.022_935_322_010_529_225,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_18,
    0.140_653_259_715_525_92,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_83,
];
const GAUSS_WEIGHTS: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// A piece of an adaptive rule: (start, length, Kronrod estimate, |Kronrod − Gauss|).
pub(crate) type Piece = (f64, f64, f64, f64);

/// ∫ f over [start, start + length] by the 15-point Gauss–Kronrod rule, with its embedded
/// 7-point Gauss rule for the error estimate.
pub(crate) fn gauss_kronrod(start: f64, length: f64, f: impl Fn(f64) -> f64) -> Piece {
    let mut kronrod = 0.0;
    let mut gauss = 0.0;
    for (k, (x, weight)) in KRONROD_NODES.iter().zip(KRONROD_WEIGHTS).enumerate() {
        let signs: &[f64] = if *x == 0.0 { &[1.0] } else { &[1.0, -1.0] };
        for sign in signs {
            let value = 0.5 * length * f(start + 0.5 * length * (1.0 + sign * x));
            kronrod += weight * value;
            if k % 2 == 1 {
                gauss += GAUSS_WEIGHTS[k / 2] * value;
            }
        }
    }
    (start, length, kronrod, (kronrod - gauss).abs())
}

/// The 15 points of the Kronrod rule on [start, start + length] with their weights (which add
/// up to `length`): for integrals that share their integrand's values.
pub(crate) fn kronrod_points(start: f64, length: f64) -> impl Iterator<Item = (f64, f64)> {
    KRONROD_NODES
        .iter()
        .zip(KRONROD_WEIGHTS)
        .flat_map(move |(&x, weight)| {
            let signs: &[f64] = if x == 0.0 { &[1.0] } else { &[1.0, -1.0] };
            signs.iter().map(move |sign| {
                (
                    start + 0.5 * length * (1.0 + sign * x),
                    0.5 * length * weight,
                )
            })
        })
}

/// [`gauss_kronrod`] after the substitution x = start + length·(3t² − 2t³), t ∈ [0, 1], which
/// turns a square-root edge or a kink at either end into a smooth one.
pub(crate) fn smoothed_gauss_kronrod(start: f64, length: f64, f: impl Fn(f64) -> f64) -> Piece {
    let (_, _, kronrod, error) = gauss_kronrod(0.0, 1.0, |t| {
        length * 6.0 * t * (1.0 - t) * f(start + length * t * t * (3.0 - 2.0 * t))
    });
    (start, length, kronrod, error)
}

/// The sum of `pieces`' estimates, the piece with the largest error halved by `rule` until
/// the errors add up to less than `relative` of the sum plus `absolute`, or there are
/// `max_pieces` pieces: (sum, pieces). No pieces: (0, 0).
pub(crate) fn adaptive_gauss_kronrod(
    mut pieces: Vec<Piece>,
    relative: f64,
    absolute: f64,
    max_pieces: usize,
    rule: impl Fn(f64, f64) -> Piece,
) -> (f64, usize) {
    if pieces.is_empty() {
        return (0.0, 0);
    }
    loop {
        let (sum, error) = pieces
            .iter()
            .fold((0.0, 0.0), |(m, e), piece| (m + piece.2, e + piece.3));
        if error <= relative * sum + absolute || pieces.len() >= max_pieces {
            return (sum, pieces.len());
        }
        let worst = pieces
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.3.total_cmp(&b.1.3))
            .map_or(0, |(i, _)| i);
        let (start, length, _, _) = pieces.swap_remove(worst);
        pieces.push(rule(start, 0.5 * length));
        pieces.push(rule(start + 0.5 * length, 0.5 * length));
    }
}
