//! The one-choice-at-a-time settings: each choice of one preset switched to the other's
//! (matching criterion, search grid, window, distance centre, ΔE_max, cap, passes).

use ifslab_strategies::problems::fractal_coding::{
    EncoderConfig, Matching, Preset, Reduction, SearchGrid,
};

use super::Variant;
use super::tables::cap_name;

/// The settings of the one-choice-at-a-time table: the plain encoder's matching × grid (and
/// a few windows), then each refined preset with one of its choices switched to the other's.
pub(super) fn ablation_variants() -> Vec<Variant> {
    let mut v = Vec::new();
    let plain = Preset::Ifslab.encoder(false);
    for grid in SearchGrid::ALL {
        for matching in Matching::ALL {
            v.push(Variant {
                group: "plain",
                label: format!("{matching}, {grid}"),
                encoder: EncoderConfig {
                    matching: *matching,
                    grid: *grid,
                    ..plain.clone()
                },
                passes: 0,
            });
        }
    }
    for (matching, grid) in [
        (Matching::MeanRemoved, SearchGrid::All),
        (Matching::Raw, SearchGrid::Even),
    ] {
        v.push(Variant {
            group: "plain",
            label: format!("{matching}, {grid}, binomial R"),
            encoder: EncoderConfig {
                matching,
                grid,
                reduction: Reduction::Binomial,
                ..plain.clone()
            },
            passes: 0,
        });
    }
    for window in [8u32, 32] {
        for (matching, grid) in [
            (Matching::MeanRemoved, SearchGrid::All),
            (Matching::Raw, SearchGrid::Even),
        ] {
            v.push(Variant {
                group: "plain",
                label: format!("{matching}, {grid}, window {window}"),
                encoder: EncoderConfig {
                    matching,
                    grid,
                    window,
                    ..plain.clone()
                },
                passes: 0,
            });
        }
    }
    for (from, to) in [
        (Preset::Paper, Preset::Ifslab),
        (Preset::Ifslab, Preset::Paper),
    ] {
        let group = match from {
            Preset::Paper => "refined, from paper",
            Preset::Ifslab => "refined, from ifslab",
        };
        let (f, t) = (from.encoder(true), to.encoder(true));
        let (fp, tp) = (from.refine().passes, to.refine().passes);
        let with = |label: String, encoder: EncoderConfig, passes: usize| Variant {
            group,
            label,
            encoder,
            passes,
        };
        v.push(with(format!("{from} (refined)"), f.clone(), fp));
        v.push(with(
            format!("distance {}", t.distance),
            EncoderConfig {
                distance: t.distance,
                ..f.clone()
            },
            fp,
        ));
        v.push(with(
            format!("ΔE_max {}", t.delta_e_max),
            EncoderConfig {
                delta_e_max: t.delta_e_max,
                ..f.clone()
            },
            fp,
        ));
        v.push(with(
            format!("cap {}", cap_name(t.max_candidates)),
            EncoderConfig {
                max_candidates: t.max_candidates,
                ..f.clone()
            },
            fp,
        ));
        v.push(with(format!("{tp} passes"), f.clone(), tp));
        v.push(with(
            format!("matching {}", t.matching),
            EncoderConfig {
                matching: t.matching,
                ..f.clone()
            },
            fp,
        ));
        v.push(with(
            format!("grid {}", t.grid),
            EncoderConfig {
                grid: t.grid,
                ..f.clone()
            },
            fp,
        ));
    }
    debug_assert!(v.iter().all(|x| x.encoder.validate().is_ok()));
    v
}
