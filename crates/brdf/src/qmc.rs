//! The (0, 2)-sequence of Sobol's first two dimensions, for the pdf quadrature of Sec. 3.4.
//!
//! Point i is (x, y) with x the base-2 radical inverse of i and y = ⊕ₖ bitₖ(i)·vₖ, where the
//! direction numbers of the second dimension are v₀ = 2³¹ and vₖ = vₖ₋₁ ⊕ (vₖ₋₁ >> 1) (the
//! Pascal matrix mod 2). Every 2ᵐ consecutive points from index 0 put exactly one point in each
//! elementary interval of area 2⁻ᵐ: the (0, 2)-net property (Keller et al. 2012).

/// Point `index` of the (0, 2)-sequence, in [0, 1)².
#[must_use]
pub(crate) fn zero_two_point(index: u32) -> [f64; 2] {
    let x = index.reverse_bits();
    let mut y = 0u32;
    let mut direction = 1u32 << 31;
    let mut bits = index;
    while bits != 0 {
        if bits & 1 == 1 {
            y ^= direction;
        }
        bits >>= 1;
        direction ^= direction >> 1;
    }
    let scale = 1.0 / 4_294_967_296.0;
    [f64::from(x) * scale, f64::from(y) * scale]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_64_points_form_a_zero_two_net() {
        let points: Vec<[f64; 2]> = (0..64).map(zero_two_point).collect();
        for a in 0..=6 {
            let (nx, ny) = (1u32 << a, 1u32 << (6 - a));
            let mut cells = vec![0u32; 64];
            for p in &points {
                let (cx, cy) = ((p[0] * f64::from(nx)) as u32, (p[1] * f64::from(ny)) as u32);
                cells[(cy * nx + cx) as usize] += 1;
            }
            assert!(
                cells.iter().all(|&c| c == 1),
                "intervals 2^-{a} x 2^-{}",
                6 - a
            );
        }
    }
}
