//! How the tasks of an array job share a sweep (`rsasim sweep FILE --shard K/N`).
//!
//! Each point is a scenario, and its runs are split as [`crate::shard`] splits any scenario's:
//! shard j of N holds the runs at positions j, j + N, j + 2N, … of the point's protocol. Task K
//! of N writes one shard of every point, chosen so that the tasks deal the runs of the whole sweep
//! like cards. Take the runs of all points in sweep order (the runs of p00, then those of p01, …):
//! run r of point p has the global position g = o_p + r, where o_p counts the runs of the points
//! before p. Run g goes to task g mod N, so task K writes shard j = (K − o_p) mod N of point p.
//!
//! Every task thus gets ⌊T/N⌋ or ⌈T/N⌉ of the sweep's T runs (the remainders of the points do
//! not pile up on the first tasks), every point is spread over all tasks (a costlier point costs
//! every task alike), and every piece is an ordinary shard of its point: its folder and manifest
//! are those `rsasim POINT.toml --shard j/N` writes, and `rsasim merge` joins them.

use crate::shard::ShardSpec;

/// For a sweep whose points have `run_counts` runs (in sweep order), the shard of every point
/// that `task` writes (see the module documentation).
pub fn point_shards(run_counts: &[usize], task: ShardSpec) -> Vec<ShardSpec> {
    let n = task.count;
    let mut before = 0usize;
    run_counts
        .iter()
        .map(|&runs| {
            let index = (task.index + n - before % n) % n;
            before = before.wrapping_add(runs);
            ShardSpec { index, count: n }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shard::runs_of_shard;

    fn spec(k: usize, n: usize) -> ShardSpec {
        ShardSpec::new(k, n).unwrap()
    }

    #[test]
    fn the_tasks_deal_the_whole_sweeps_runs_round_robin() {
        // By hand: points of 3, 5 and 2 runs in 4 tasks. Global positions 0..10: p00 holds
        // 0, 1, 2; p01 holds 3..8; p02 holds 8, 9. Task 1 takes 1, 5, 9: run 1 of p00 (shard 1),
        // run 2 of p01 (its offset 3: shard (1 − 3) mod 4 = 2), run 1 of p02 (offset 8: shard 1).
        assert_eq!(
            point_shards(&[3, 5, 2], spec(1, 4)),
            [spec(1, 4), spec(2, 4), spec(1, 4)]
        );
        assert_eq!(
            point_shards(&[3, 5, 2], spec(0, 4)),
            [spec(0, 4), spec(1, 4), spec(0, 4)]
        );
        for counts in [
            vec![3, 3, 3],
            vec![3, 5, 2],
            vec![0, 7, 1, 20],
            vec![1; 9],
            vec![40],
        ] {
            let total: usize = counts.iter().sum();
            for n in [1, 2, 3, 4, 7, 50] {
                let mut owner = vec![usize::MAX; total];
                for k in 0..n {
                    let shards = point_shards(&counts, spec(k, n));
                    let mut held = 0;
                    let mut offset = 0;
                    for (&runs, s) in counts.iter().zip(&shards) {
                        for r in runs_of_shard(runs, *s) {
                            assert_eq!(owner[offset + r], usize::MAX, "a run dealt twice");
                            owner[offset + r] = k;
                            held += 1;
                        }
                        offset += runs;
                    }
                    // Balanced over the whole sweep.
                    assert!(
                        held == total / n || held == total.div_ceil(n),
                        "{counts:?} {n}"
                    );
                }
                // Every run to exactly one task: task g mod N.
                let expected: Vec<usize> = (0..total).map(|g| g % n).collect();
                assert_eq!(owner, expected, "{counts:?} N = {n}");
                // Every task writes one shard of every point, and the tasks write all N of each.
                for p in 0..counts.len() {
                    let mut of_point: Vec<usize> = (0..n)
                        .map(|k| point_shards(&counts, spec(k, n))[p].index)
                        .collect();
                    of_point.sort_unstable();
                    assert_eq!(of_point, (0..n).collect::<Vec<_>>());
                }
            }
        }
    }
}
