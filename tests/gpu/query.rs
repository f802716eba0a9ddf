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
            KernelWork::from(work)
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
            let total = work.iter().fold(QueryWork::default(), |mut sum, &w| {
                sum += w.into();
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

/// The tile kernel (a G-buffer's 8x8 tiles, one two-ended query a thread) answers and counts as
/// its CPU twin does, query for query, in both forms of the search.
#[test]
fn tile_kernel_matches_its_cpu_twin_answer_for_answer_and_count_for_count() {
    use cssm_runtime::{
        common::camera::View,
        visibility::tiles::{TileKernel, TileSenders, tile_pixels, tiles_cpu},
    };
    let gpu = gpu();
    let (scene, file) = cornell();
    let view = View::of_scene(scene, 40, 28);
    let (pixels, tiles_x) = tile_pixels(scene, &view);
    assert_eq!((pixels.len(), tiles_x), (5 * 4 * 64, 5));
    let senders = TileSenders::spread(file.texels.len() as u32, 6);
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let expected = tiles_cpu(&query, &pixels, senders, |_, _| QueryWork::default());
    let mut cssm =
        CssmGpu::new(&gpu.device, &gpu.queue, file, QueryOptions::default()).expect("upload");
    for search_loop in [false, true] {
        cssm.search_loop = search_loop;
        let (answers, work) = TileKernel::new(gpu, &cssm, true)
            .run(gpu, &cssm, &pixels, tiles_x, senders, None)
            .expect("tile kernel");
        assert_eq!(answers.len(), expected.len());
        let mut seen = 0;
        for (i, ((gpu_answer, gpu_work), (cpu_answer, cpu_work))) in
            answers.iter().zip(&work).zip(&expected).enumerate()
        {
            assert!(
                (gpu_answer - cpu_answer).abs() <= 1e-4,
                "query {i}: GPU {gpu_answer}, CPU {cpu_answer}"
            );
            assert_eq!(
                *gpu_work,
                KernelWork::from(*cpu_work),
                "query {i}, loop {search_loop}"
            );
            seen += usize::from(*cpu_answer >= 0.0);
        }
        // Most pixels see the box (a sixth of the entries pad the last row of tiles), and both
        // ends are asked.
        assert!(seen > expected.len() / 2, "{seen} of {}", expected.len());
        let texel_loads: u32 = work.iter().map(|w| w.texel_loads).sum();
        assert!(texel_loads as usize > 2 * seen);
    }
}
