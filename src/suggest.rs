//! "Did you mean" for names typed on the command line and in sweep and scene files: the
//! candidate closest to a mistyped word by edit distance.

/// Edits at most this many (insertions, deletions, substitutions, transpositions of neighbours)
/// for a candidate to be suggested; fewer for short words (see [`closest`]).
const MAX_EDITS: usize = 2;

/// The optimal string alignment distance between `a` and `b`, by characters: the fewest
/// insertions, deletions, substitutions and swaps of two neighbouring characters that turn one
/// into the other (Levenshtein's distance with swaps, each substring edited once).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    // Three rows of the dynamic programme: two rows back (for swaps), the last and this one.
    let mut before: Vec<usize> = vec![0; b.len() + 1];
    let mut last: Vec<usize> = (0..=b.len()).collect();
    for i in 1..=a.len() {
        let mut row = vec![i; b.len() + 1];
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            row[j] = (last[j] + 1).min(row[j - 1] + 1).min(last[j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                row[j] = row[j].min(before[j - 2] + 1);
            }
        }
        before = std::mem::replace(&mut last, row);
    }
    last[b.len()]
}

/// The candidate closest to `word` (ignoring ASCII case), when it is close enough to be a typo:
/// at most [`MAX_EDITS`] edits, and fewer edits than half of `word`'s characters (so that
/// `x` does not suggest `y`). Ties go to the first candidate.
pub fn closest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let word = word.to_ascii_lowercase();
    let limit = MAX_EDITS.min(word.chars().count().saturating_sub(1) / 2);
    candidates
        .into_iter()
        .map(|c| (edit_distance(&word, &c.to_ascii_lowercase()), c))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// `"; did you mean 'NAME'?"` for the candidate [`closest`] to `word`, else empty: to follow
/// the unknown name in a message.
pub fn did_you_mean<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    closest(word, candidates).map_or_else(String::new, |c| format!("; did you mean '{c}'?"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_counts_insertions_deletions_substitutions_and_swaps() {
        assert_eq!(edit_distance("", ""), 0);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("abc", ""), 3);
        assert_eq!(edit_distance("pyramid", "pyramid"), 0);
        assert_eq!(edit_distance("pyrmid", "pyramid"), 1);
        assert_eq!(edit_distance("pyramidd", "pyramid"), 1);
        assert_eq!(edit_distance("pyrbmid", "pyramid"), 1);
        assert_eq!(edit_distance("pyarmid", "pyramid"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("ca", "abc"), 3);
        assert_eq!(edit_distance("höhe", "hohe"), 1);
    }

    #[test]
    fn closest_suggests_only_near_candidates() {
        let methods = ["points", "pyramid", "pyramid-hybrid", "compute", "ewa"];
        assert_eq!(closest("pyrmid", methods), Some("pyramid"));
        assert_eq!(closest("PYRAMID-HYBIRD", methods), Some("pyramid-hybrid"));
        assert_eq!(closest("comptue", methods), Some("compute"));
        assert_eq!(closest("point", methods), Some("points"));
        assert_eq!(closest("splat", methods), None);
        assert_eq!(closest("nope", methods), None);
        // Short words allow fewer edits: one for 3 or 4 characters, none below.
        assert_eq!(closest("ew", methods), None);
        assert_eq!(closest("eva", methods), Some("ewa"));
        assert_eq!(closest("exb", methods), None);
        assert_eq!(closest("cul", ["radius", "color", "cull"]), Some("cull"));
        assert_eq!(did_you_mean("cul", ["cull"]), "; did you mean 'cull'?");
        assert_eq!(did_you_mean("zzz", ["cull"]), "");
    }
}
