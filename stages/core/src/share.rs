//! Independent work shared between the calling thread and a helper thread
//! (the pose stage's, beside the stages' CPU): both take the next item in
//! turn until none is left, so a helper the scheduler holds back costs at
//! most the item it has taken, and the results, in order, do not depend on
//! which thread computed which.

use std::sync::atomic::{AtomicUsize, Ordering};

/// `work(i, state)` for every `i` in `0..n`, in order of `i`: on the
/// calling thread with `mine` and, when there is a `helper`, on its first
/// thread with `theirs`.
pub fn in_turn<S: Send, T: Send>(
    helper: Option<&rayon::ThreadPool>,
    n: usize,
    mine: &mut S,
    theirs: &mut S,
    work: impl Fn(usize, &mut S) -> T + Sync,
) -> Vec<T> {
    let Some(pool) = helper.filter(|_| n >= 2) else {
        return (0..n).map(|i| work(i, mine)).collect();
    };
    let next = AtomicUsize::new(0);
    let take = |state: &mut S| {
        let mut done = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= n {
                return done;
            }
            done.push((i, work(i, state)));
        }
    };
    let mut other = Vec::new();
    let mut done = pool.in_place_scope(|scope| {
        scope.spawn(|_| other = take(theirs));
        take(mine)
    });
    done.append(&mut other);
    done.sort_unstable_by_key(|&(i, _)| i);
    done.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_is_done_once_in_order_whoever_does_it() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let (mut mine, mut theirs) = (0usize, 0usize);
        let out = in_turn(Some(&pool), 1000, &mut mine, &mut theirs, |i, count| {
            *count += 1;
            // Slow enough that the helper wakes before the calling thread
            // has taken everything.
            std::thread::sleep(std::time::Duration::from_micros(20));
            i * i
        });
        assert_eq!(out, (0..1000).map(|i| i * i).collect::<Vec<_>>());
        assert_eq!(mine + theirs, 1000);
        assert!(theirs > 0, "the helper took nothing");
        let alone = in_turn(None, 3, &mut mine, &mut theirs, |i, _| i);
        assert_eq!(alone, vec![0, 1, 2]);
    }
}
