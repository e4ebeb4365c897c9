//! C's `GlintDistribution` constants are glint-brdf's table of kinds: one `GLINT_<NAME>` per
//! kind, numbered by its index in `DistributionKind::ALL`, and nothing else.

use glint_brdf::DistributionKind;

#[test]
fn header_constants_are_the_table_of_kinds() {
    let header = include_str!("../include/glint.h");
    let start = header
        .find("typedef enum GlintDistribution {")
        .expect("the header declares GlintDistribution");
    let end = start
        + header[start..]
            .find("} GlintDistribution;")
            .expect("it ends");
    let constants: Vec<(String, u32)> = header[start..end]
        .lines()
        .filter_map(|line| {
            let (name, value) = line.trim().trim_end_matches(',').split_once(" = ")?;
            Some((name.to_owned(), value.parse().ok()?))
        })
        .collect();
    let expected: Vec<(String, u32)> = DistributionKind::ALL
        .iter()
        .map(|kind| (format!("GLINT_{}", kind.name().to_uppercase()), kind.code()))
        .collect();
    assert_eq!(constants, expected);
    for kind in DistributionKind::ALL {
        assert_eq!(DistributionKind::from_code(kind.code()), Some(kind));
    }
    assert_eq!(
        DistributionKind::from_code(DistributionKind::ALL.len() as u32),
        None
    );
}
