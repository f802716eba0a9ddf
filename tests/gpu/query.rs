//! The lean query's shape and its work counters (issue 48): the kernel composed with
//! `CSSM_COUNTERS` counts, query by query, exactly the work the CPU twin counts
//! (`VisibilityQuery::visibility_from_surface_counted`), the looped search answers as the
//! unrolled one does, and the search takes no more steps than the file's longest run list needs.

use cssm_formats::visibility::{QueryOptions, QueryWork, VisibilityQuery};
use cssm_runtime::{
    load::CssmGpu,
    visibility::{KernelWork, QueryKernel},
};

use super::{cornell, gpu, random_pairs};

/// The CPU twin's work for each pair, as the kernel's counters lay it out.
fn cpu_work(
    query: &VisibilityQuery,
    pairs: &[cssm_runtime::visibility::QueryPair],
) -> Vec<KernelWork> {
    pairs
        .iter()
        .map(|pair| {
            let mut work = QueryWork::default();
            query.visibility_from_surface_counted(
                pair.sender_triangle as usize,
                pair.sender_bary,
                pair.receiver.into(),
                Some(pair.receiver_normal.into()),
                &mut work,
            );
            KernelWork {
                taps: work.taps as u32,
                search_steps: work.search_steps as u32,
                texel_loads: work.texel_loads as u32,
                sender_loads: work.sender_loads as u32,
            }
        })
        .collect()
}

#[test]
fn kernel_counters_match_the_cpu_twin_query_for_query() {
    let gpu = gpu();
    let (scene, file) = cornell();
    let pairs = random_pairs(scene, 20_000, 23);
    let unfiltered = QueryOptions {
        pcf: false,
        sender_filter: false,
        both_ends: false,
        ..Default::default()
    };
    for options in [QueryOptions::default(), unfiltered] {
        let mut cssm = CssmGpu::new(&gpu.device, &gpu.queue, file, options).expect("upload");
        let plain = QueryKernel::new(gpu, &cssm)
            .run(gpu, &cssm, &pairs, None)
            .expect("plain kernel");
        let query = VisibilityQuery::new(file, options);
        let expected = cpu_work(&query, &pairs);
        for search_loop in [false, true] {
            cssm.search_loop = search_loop;
            let (answers, work) = QueryKernel::counting(gpu, &cssm)
                .run_counted(gpu, &cssm, &pairs)
                .expect("counting kernel");
            // The counters and the search's form change no answer.
            assert_eq!(answers, plain, "loop {search_loop}, {options:?}");
            let differ = work.iter().zip(&expected).filter(|(g, c)| g != c).count();
            let first = work.iter().zip(&expected).find(|(g, c)| g != c);
            assert_eq!(
                differ, 0,
                "loop {search_loop}, {options:?}: {differ} queries counted otherwise, first {first:?}"
            );
            let total = work.iter().fold(QueryWork::default(), |mut sum, w| {
                sum += QueryWork {
                    taps: w.taps.into(),
                    search_steps: w.search_steps.into(),
                    texel_loads: w.texel_loads.into(),
                    sender_loads: w.sender_loads.into(),
                    ..Default::default()
                };
                sum
            });
            // Something was counted: the test cannot pass on zeros.
            assert!(total.taps > pairs.len() as u64 / 2 && total.search_steps > total.taps);
            eprintln!("{options:?}, loop {search_loop}: {total:?}");
        }
    }
}

/// The search is bounded by the file's longest run list: the bit length of its length, enough
/// for every list (the twin tests find every run the CPU's search finds) and no more.
#[test]
fn the_search_takes_the_steps_of_the_longest_run_list() {
    let gpu = gpu();
    let (_, file) = cornell();
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, file, Default::default()).expect("upload");
    let longest = file.runs.longest_list();
    assert!(longest > 1);
    assert!(1 << (cssm.search_steps - 1) <= longest && longest < 1 << cssm.search_steps);
    assert!(cssm.search_steps < cssm_runtime::shaders::MAX_SEARCH_STEPS);
}
