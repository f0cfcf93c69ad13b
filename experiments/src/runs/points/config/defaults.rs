//! ifslab's choices for K maps and the paper's: orientations of the re-orientation search, independent runs, and the six choices `paper = true` fixes.

use super::*;

/// The six choices `paper = true` fixes, as (schedule, by, reorient, every, recentre, update).
pub(super) type Choices = (
    PreselectSchedule,
    PreselectBy,
    usize,
    usize,
    bool,
    ComponentUpdate,
);

/// ifslab's orientations per component of the re-orientation search for point clouds of
/// three or more maps: turns by 10° in 2-D, 35 Haar-random rotations in 3-D (12, the EM
/// module's own default, left a third of the robustness suite's 3-D clouds unrecovered;
/// robustness/README.md).
pub const DEFAULT_REORIENT: usize = 36;

/// Candidate × code evaluations one component's search costs at the default for four maps
/// at depth 6 (36 orientations, 5,461 codes).
pub(super) const REORIENT_BUDGET: usize = DEFAULT_REORIENT * 4 * 5461;

/// ifslab's orientations per component for K maps at depth D. A code of one or two maps
/// gets as many as cost what 36 cost four maps at depth 6 (a search costs K × orientations
/// × codes): 3,096 at depth 6, at most 4,096; sets that large are screened on an eighth of
/// the points (`em::reorient`). Its pieces are few and cheap to search, and a piece turned
/// wrong was the commonest way a two-map dust failed; on the robustness suite's two tuning
/// splits the twelve 3-D two-map clouds kept their count (11 of 12) and rose from 0.89 to
/// 0.95 mean agreement. Three or more maps get [`DEFAULT_REORIENT`] (239 for three maps,
/// at the same cost, was better on one tuning split and worse on the other).
pub fn default_reorient(k: usize, depth: usize) -> usize {
    if k > 2 {
        return DEFAULT_REORIENT;
    }
    let per = k.max(1).saturating_mul(code_count(k.max(1), depth).max(1));
    (REORIENT_BUDGET / per).clamp(DEFAULT_REORIENT, 4096)
}

/// ifslab's independent runs for K maps, one kept (`keep`): 8 for up to
/// three maps, 4 for four and five (the robustness suite's range), 1 from six on. Eight runs
/// of two or three maps cost about what four runs of five do: on the three tuning splits'
/// 48 two- and three-map 3-D clouds they recovered 47 against 45 with four (mean agreement
/// 0.936 → 0.962), on the 24 such 2-D clouds 23 either way (mean 0.978 → 0.986). Four runs
/// against one: the held-out likelihood picked a right fit among the runs every time one was
/// there, 24 of 24 two- and three-map 3-D clouds recovered against 20 with one run; for four
/// maps 21 of 24 3-D clouds against 19 and 12 of 12 2-D clouds either way with a higher mean
/// agreement; for five maps 12 of 12 3-D clouds against 11 on the third split and the mean
/// agreement up on all three. With the E-step that skips far codes, four runs of five maps
/// take about what one took before it (a fit of five maps at depth 6: 29 s, now 6 s a run).
pub fn default_runs(k: usize) -> usize {
    match k {
        0..=3 => 8,
        4 | 5 => 4,
        _ => 1,
    }
}

pub(super) fn choices(paper: bool, k: usize, depth: usize) -> Choices {
    let e = if paper {
        EmConfig::paper()
    } else {
        EmConfig::default()
    };
    (
        if e.curriculum {
            PreselectSchedule::Curriculum
        } else {
            PreselectSchedule::Fixed
        },
        e.preselect_by,
        if paper {
            e.reorient.rotations
        } else {
            default_reorient(k, depth)
        },
        e.reorient.every,
        e.recentre,
        e.mstep.update,
    )
}
