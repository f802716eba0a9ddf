//! A bake's progress (issue 23: the atlas stage of a large mesh ran for minutes without a
//! word): every stage is reported, in order, and each stage's count only grows.

mod common;

use cssm_bake::{Progress, Stage, bake};

#[test]
fn every_stage_is_reported_in_order_and_counts_up() {
    let (scene, options) = common::cornell_small();
    let mut seen: Vec<Progress> = Vec::new();
    let baked = bake(&scene, &options, &mut |p| seen.push(p)).unwrap();
    // The stages in the order they run, none skipped, none coming back.
    let mut stages: Vec<Stage> = seen.iter().map(|p| p.stage).collect();
    stages.dedup();
    assert_eq!(
        stages,
        [
            Stage::Charts,
            Stage::Parameterize,
            Stage::Pack,
            Stage::Order,
            Stage::Maps
        ]
    );
    for stage in stages {
        let of_stage: Vec<&Progress> = seen.iter().filter(|p| p.stage == stage).collect();
        assert!(
            of_stage.windows(2).all(|w| w[0].done <= w[1].done),
            "{stage:?}: {of_stage:?}"
        );
        let last = of_stage.last().unwrap();
        match stage {
            // xatlas' percentages end at 100.
            Stage::Charts | Stage::Parameterize => assert_eq!((last.done, last.total), (100, 100)),
            Stage::Pack => assert!(last.done >= 1 && last.total == 0, "{last:?}"),
            Stage::Order => assert_eq!(last.total, 0),
            Stage::Csm => unreachable!("the Cornell box has no moving objects"),
            Stage::Maps => {
                let maps = baked.file.texels.len() as u64;
                assert_eq!((last.done, last.total), (maps, maps));
            }
        }
    }
}
