//! Tidy checks: the user docs' lists of distribution names, and the sampler count the README
//! states, against the table they describe. A contributor who adds a kind is told which file
//! to update instead of left to grep.

use std::path::Path;

use glint_brdf::DistributionKind;

/// The files that list the distributions users may name (tables of allowed values, docstrings,
/// an example error message), from the repository's root.
const LISTING_FILES: [&str; 9] = [
    "README.md",
    "scenes/README.md",
    "docs/eval.md",
    "python/README.md",
    "crates/brdf/README.md",
    "crates/eval/src/material.rs",
    "python/glint/__init__.py",
    "python/mitsuba/glint_vectorized.py",
    "python/mitsuba/glint_lobe.py",
];

fn read(relative: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Whether `line` names `kind` by its name (as scene files, eval, C and Python take it), as a
/// whole word: "ashikhmin_shirley", not "Ashikhmin–Shirley" in prose (which may name a kind
/// alone, or two of them, for a fact about those).
fn names(line: &str, kind: DistributionKind) -> bool {
    let is_word_char = |c: char| c.is_ascii_alphanumeric() || c == '_';
    line.match_indices(kind.name()).any(|(at, name)| {
        let before = line[..at].chars().next_back();
        let after = line[at + name.len()..].chars().next();
        !before.is_some_and(is_word_char) && !after.is_some_and(is_word_char)
    })
}

/// Every line of the listing files that names two kinds or more names them all, and every
/// such file has one: a list of the distributions is a list of the table's rows.
#[test]
fn every_list_of_distributions_names_the_whole_table() {
    let kinds = DistributionKind::ALL;
    assert!(
        kinds.len() >= 2,
        "the check needs two kinds to recognise a list"
    );
    let mut problems = Vec::new();
    for file in LISTING_FILES {
        let text = read(file);
        let mut lists = 0;
        for (number, line) in text.lines().enumerate() {
            let named: Vec<_> = kinds.iter().filter(|&&k| names(line, k)).collect();
            if named.len() < 2 {
                continue;
            }
            lists += 1;
            let missing: Vec<&str> = kinds
                .iter()
                .filter(|&&k| !names(line, k))
                .map(|k| k.name())
                .collect();
            if !missing.is_empty() {
                problems.push(format!(
                    "{file}:{}: a list of distributions without {}: update it to the table \
                     of crates/brdf/src/distribution.rs ({})",
                    number + 1,
                    missing.join(", "),
                    DistributionKind::names()
                ));
            }
        }
        if lists == 0 {
            problems.push(format!(
                "{file}: lists no distributions any more: take it off LISTING_FILES in \
                 tests/tests/doc_lists.rs, or list {}",
                DistributionKind::names()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The README's figure "all N samplers pass chi-square" is the number of sampler cases
/// `cargo xtask validate` tests.
#[test]
fn the_readme_counts_the_samplers_validate_tests() {
    let cases = glint_tests::sampling::sampler_cases().len();
    let readme = read("README.md");
    let stated: Vec<usize> = readme
        .match_indices(" samplers pass")
        .filter_map(|(at, _)| readme[..at].split_whitespace().next_back()?.parse().ok())
        .collect();
    assert_eq!(
        stated,
        [cases],
        "README.md: \"all N samplers pass chi-square\" should say {cases} (the sampler cases \
         of tests/src/sampling.rs)"
    );
}

/// The matcher itself: names as users type them, not inside other words or in prose.
#[test]
fn names_are_recognised_as_users_type_them() {
    use DistributionKind::{AshikhminShirley, Beckmann, Ggx};
    assert!(names("`\"ashikhmin_shirley\"`", AshikhminShirley));
    assert!(names("use one of beckmann, ggx", Ggx));
    assert!(!names("Beckmann, GGX and Ashikhmin–Shirley", Ggx));
    assert!(!names("ashikhmin alone", AshikhminShirley));
    assert!(!names("beckmannish", Beckmann));
    assert!(!names("a_ggx", Ggx));
}
