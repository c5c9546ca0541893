//! The trials of an export: what one folder of `rsasim export` holds and what one file of
//! XMALab's or Autoscoper's results read back by `rsasim evaluate` covers. A run without a frame
//! is a trial of one frame, named by its run id; the frames of a sequence (`truth.json`'s
//! `frame`) are one trial, named by the sequence id, its frames in frame order. Both clients
//! number a trial's frames by its images sorted by name (Autoscoper's `Video::Video` sorts the
//! camera folder, XMALab's `CameraBox` sorts the files chosen), so a frame's images carry its
//! number, [`image_number`], zero-padded to one width.
//!
//! An output may hold only some frames of a sequence (a shard deals a sequence's frames out like
//! runs): the trial then holds the frames present, still numbered by their frame index, and
//! frame k of the trial (its k-th image, the k-th line of a tracking) is the k-th frame present.

use std::collections::BTreeMap;
use std::path::Path;

use crate::diagnostic::{Diagnostic, cut};
use crate::expand::{FrameState, Run};

/// A trial's name and folder: the sequence id of a frame, the run id otherwise.
pub fn trial_id(run: &Run) -> &str {
    run.frame.as_ref().map_or(&run.id, |f| f.sequence.as_str())
}

/// A trial as messages name it: `run n0-r00` or `sequence n0-r00`.
pub fn trial_label(run: &Run) -> String {
    match &run.frame {
        None => format!("run {}", run.id),
        Some(f) => format!("sequence {}", f.sequence),
    }
}

/// The number in a frame's image names, `<exposure>-<detector>.<number>.tif`: the frame's
/// index plus one, at least four digits and as many as the sequence's last frame needs, so that
/// name order is frame order; `0001` for a run without a frame.
pub fn image_number(frame: Option<&FrameState>) -> String {
    match frame {
        None => "0001".into(),
        Some(f) => {
            let width = f.count.to_string().len().max(4);
            format!("{:0width$}", u64::from(f.index) + 1)
        }
    }
}

/// Groups `items` into trials by [`trial_id`], in the order of each trial's first item, the
/// frames of a sequence by index. `run_of` gives an item's run, `file_of` the truth file that
/// errors name. Refused: a run and a sequence of the same name (one folder for both), frames
/// of one sequence that disagree on its frame count.
pub fn group<T>(
    items: Vec<T>,
    run_of: impl Fn(&T) -> &Run,
    file_of: impl Fn(&T) -> std::path::PathBuf,
) -> Result<Vec<(String, Vec<T>)>, Vec<Diagnostic>> {
    let mut order: Vec<String> = Vec::new();
    let mut by_id: BTreeMap<String, Vec<T>> = BTreeMap::new();
    for item in items {
        let id = trial_id(run_of(&item)).to_string();
        if let Some(first) = by_id.get(&id).and_then(|v| v.first()) {
            check_same_trial(run_of(first), run_of(&item), &file_of(&item))?;
        } else {
            order.push(id.clone());
        }
        by_id.entry(id).or_default().push(item);
    }
    Ok(order
        .into_iter()
        .map(|id| {
            let mut frames = by_id.remove(&id).unwrap_or_default();
            frames.sort_by_key(|t| run_of(t).frame.as_ref().map_or(0, |f| f.index));
            (id, frames)
        })
        .collect())
}

/// Whether `run` (in `file`) may share a trial with `first`: both frames of one sequence with
/// one frame count (two runs without a frame never share an id: run folders are named by it).
fn check_same_trial(first: &Run, run: &Run, file: &Path) -> Result<(), Vec<Diagnostic>> {
    let refused = match (&first.frame, &run.frame) {
        (Some(a), Some(b)) if a.count == b.count => return Ok(()),
        (Some(a), Some(b)) => Diagnostic::file_error(
            file,
            format!(
                "frame {} of sequence {} says the sequence has {} frames, run {} says {}",
                b.index,
                cut(&b.sequence),
                b.count,
                first.id,
                a.count
            ),
        )
        .with_help("the frames of a sequence come from one scenario: remove run folders copied from another output"),
        _ => Diagnostic::file_error(
            file,
            format!(
                "run {} and a sequence both go by the name `{}`, which names one trial folder",
                cut(&run.id),
                cut(trial_id(run))
            ),
        )
        .with_help("an output holds runs of one scenario, with [sequence] or without: remove run folders copied from another output"),
    };
    Err(vec![refused])
}

/// Why a results file with `found` frames (lines or rows, the `unit` named) does not fit the
/// trial of `frames` (its runs in frame order), or `None` when it does. A sequence's file holds
/// one per frame present in the output; a run's, one.
pub fn frame_count_problem(found: usize, frames: &[&Run], unit: &str) -> Option<String> {
    if found == frames.len() {
        return None;
    }
    let first = frames.first()?;
    Some(match &first.frame {
        None => {
            format!("the file holds {found} frame(s); an exported rsasim run is a one-frame trial")
        }
        Some(f) => {
            let present = if frames.len() == f.count as usize {
                String::new()
            } else {
                format!(", {} of them in this output", frames.len())
            };
            format!(
                "the file holds {found} {unit}(s), but sequence {} has {} frame(s){present}: one {unit} per frame, in frame order",
                cut(&f.sequence),
                f.count
            )
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(index: u32, count: u32) -> FrameState {
        FrameState {
            sequence: "n0-r00".into(),
            index,
            count,
            time_s: 0.0,
            joints: Vec::new(),
        }
    }

    #[test]
    fn image_numbers_are_one_based_and_sort_in_frame_order() {
        assert_eq!(image_number(None), "0001");
        assert_eq!(image_number(Some(&frame(0, 5))), "0001");
        assert_eq!(image_number(Some(&frame(99, 100))), "0100");
        // 10000 frames: the last is 10000, five digits, and so are all the others.
        assert_eq!(image_number(Some(&frame(0, 10000))), "00001");
        assert_eq!(image_number(Some(&frame(9999, 10000))), "10000");
        assert_eq!(
            image_number(Some(&frame(u32::MAX - 1, u32::MAX))),
            "4294967295"
        );
    }
}
