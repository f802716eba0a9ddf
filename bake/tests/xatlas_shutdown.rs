//! xatlas starts a pool of worker threads with every atlas and joins them when the atlas is
//! destroyed. Its vendored scheduler could lose the wake-up of a worker that was going to sleep
//! just as the pool stopped, and the join then hung forever (once in `cargo test`, in a GPU
//! test's bake; `third_party/xatlas-rs/PATCHED.md`, change 6). Many atlases created and
//! destroyed in a row hit that window now and then; a watchdog turns a hang into a failure.

use std::{
    sync::{
        Arc,
        atomic::{AtomicUsize, Ordering},
    },
    time::{Duration, Instant},
};

#[test]
fn atlases_are_destroyed_without_hanging() {
    const ATLASES: usize = 20_000;
    let done = Arc::new(AtomicUsize::new(0));
    let counter = done.clone();
    std::thread::spawn(move || {
        for _ in 0..ATLASES {
            drop(xatlas_rs::Xatlas::new());
            counter.fetch_add(1, Ordering::Relaxed);
        }
    });
    // Slow is fine (a loaded machine); no progress for 20 s is a hang.
    let (mut seen, mut since) = (0, Instant::now());
    loop {
        std::thread::sleep(Duration::from_millis(100));
        let now = done.load(Ordering::Relaxed);
        if now == ATLASES {
            return;
        }
        if now != seen {
            (seen, since) = (now, Instant::now());
        }
        assert!(
            since.elapsed() < Duration::from_secs(20),
            "destroying atlas {} of {ATLASES} hung: a worker thread was never woken",
            now + 1
        );
    }
}
