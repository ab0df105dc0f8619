//! The capture loop over any depth source and turntable.

use voxoct_kinect::DepthSource;
use voxoct_turntable::Turntable;

use super::{Event, GRAB_TIMEOUT, SessionError, TURN_TIMEOUT, device};
use crate::pipeline::SnapshotFrames;

/// Turns the table through `n` equal steps, grabbing `frames` frames at each stop;
/// `on_angle` is told the table's angle before each snapshot's frames are grabbed.
///
/// The order, which a fakenect recording for a rehearsed live scan follows
/// (examples/record_fakenect.rs): home the table; then for each snapshot `k` of `0..n` read the
/// table's angle, grab `frames` frames, and — except after the last — turn by `360°/n` and wait
/// until the table has stopped ([`TURN_TIMEOUT`]); finally shut the source down. A live
/// source has already consumed one frame when it opened.
///
/// # Errors
/// [`SessionError::Device`] from the table or the source.
pub fn capture<S: DepthSource + ?Sized>(
    source: &mut S,
    table: &mut dyn Turntable,
    mut on_angle: impl FnMut(&mut S, f32),
    n: u32,
    frames: u32,
    mut on_event: impl FnMut(Event<'_>),
) -> Result<Vec<SnapshotFrames>, SessionError> {
    on_event(Event::CaptureStarted(n));
    table.home().map_err(|e| device("turntable")(&e))?;
    let mut snapshots = Vec::with_capacity(n as usize);
    for k in 0..n {
        let angle = table.angle_deg().map_err(|e| device("turntable")(&e))? as f32;
        on_angle(source, angle);
        let grabbed = (0..frames)
            .map(|_| source.grab(GRAB_TIMEOUT))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| device("depth source")(&e))?;
        on_event(Event::Snapshot {
            index: k,
            of: n,
            angle_deg: angle,
            frames: grabbed.len(),
        });
        snapshots.push(SnapshotFrames {
            angle_deg: angle,
            frames: grabbed,
        });
        if k + 1 < n {
            let step = 360.0 / f64::from(n);
            let turned = table
                .rotate_by(step, TURN_TIMEOUT)
                .map_err(|e| device("turntable")(&e))?;
            on_event(Event::Turned {
                by_deg: turned,
                asked_deg: step,
            });
        }
    }
    on_event(Event::CaptureDone);
    source.shutdown().map_err(|e| device("depth source")(&e))?;
    Ok(snapshots)
}
