//! Live capture: a Kinect v1 through libfreenect and a networked turntable.

use voxoct_kinect::KinectDepth;

/// The settings of a [`super::Source::Kinect`], borrowed for one capture.
#[cfg_attr(not(feature = "freenect"), allow(dead_code))]
pub(super) struct Live<'a> {
    /// `HOST:PORT` of the turntable server.
    pub turntable: Option<&'a str>,
    /// Its shared secret.
    pub token: Option<&'a str>,
    /// The depth stream.
    pub depth: KinectDepth,
    /// Let libfreenect print its own messages.
    pub verbose: bool,
}

#[cfg(feature = "freenect")]
mod imp {
    use super::super::*;
    use voxoct_kinect::{KinectOptions, KinectSource};
    use voxoct_turntable::{ClientTimeouts, RemoteTurntable};

    pub(in crate::session) fn capture(
        session: &Session,
        live: &super::Live<'_>,
        config: Option<ScannerConfig>,
        params: &Params,
        on_event: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        let super::Live {
            turntable,
            token,
            depth,
            verbose,
        } = live;
        let addr = turntable.as_deref().ok_or_else(|| {
            input(
                "--turntable",
                "--kinect needs a turntable: --turntable HOST:PORT (examples/turntable_server.rs on the Pi)",
            )
        })?;
        let config = config.ok_or_else(|| {
            input(
                "--config",
                "--kinect needs --config FILE with the rig's [sensor], [rig] and [clip] (see examples/thesis-rig.toml)",
            )
        })?;
        let (n, f) = (u64::from(session.snapshots), u64::from(session.frames));
        session.check_memory(&config, params, n, n * f)?;
        // The sensor first: it is local, and without it there is nothing to turn the table for.
        if let Some(dir) = std::env::var_os("FAKENECT_PATH") {
            check_fakenect_length(Path::new(&dir), session.snapshots, session.frames)?;
        }
        let options = KinectOptions {
            depth: *depth,
            verbose: *verbose,
        };
        let mut kinect = KinectSource::open_with(0, options)
            .and_then(|k| k.with_intrinsics(config.sensor.intrinsics))
            .map_err(|e| device("Kinect")(&e))?;
        on_event(Event::SensorOpen(*depth));
        let mut table = RemoteTurntable::connect(addr, token.as_deref(), ClientTimeouts::default())
            .map_err(|e| device(format!("turntable at {addr}"))(&e))?;
        let snapshots = super::super::capture(
            &mut kinect,
            &mut table,
            |_, _| {},
            session.snapshots,
            session.frames,
            on_event,
        )?;
        Ok(Acquired {
            config,
            source: format!("Kinect v1 ({depth} depth)"),
            snapshots,
        })
    }

    /// A rehearsed live scan (FAKENECT_PATH set, libfreenect's fakenect library loaded) needs a
    /// recording long enough: opening the Kinect consumes one frame, the scan `snapshots ×
    /// frames`, and libfreenect 0.5's fakenect ends its runloop at the end of `INDEX.txt` — a
    /// grab after that crashes or waits for ever — so one frame more must follow the last one
    /// grabbed.
    fn check_fakenect_length(dir: &Path, snapshots: u32, frames: u32) -> Result<(), SessionError> {
        let count = FakenectSource::open(dir)
            .map_err(|e| input("--kinect", format!("FAKENECT_PATH: {e}")))?
            .depth_frame_count();
        let need = 2 + snapshots as usize * frames as usize;
        if count < need {
            return Err(input(
                "--kinect",
                format!(
                    "FAKENECT_PATH {}: {count} depth frames, but a live scan of {snapshots} \
                     snapshots × {frames} frames needs at least {need} (1 consumed on opening, \
                     then the scan's, then 1 more before the end of the recording); record one \
                     with the record_fakenect example",
                    dir.display(),
                ),
            ));
        }
        Ok(())
    }
}

/// Without the `freenect` feature a live scan is not possible: say how to get one.
#[cfg(not(feature = "freenect"))]
mod imp {
    use super::super::*;

    pub(in crate::session) fn capture(
        _: &Session,
        _: &super::Live<'_>,
        _: Option<ScannerConfig>,
        _: &Params,
        _: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        Err(input(
            "--kinect",
            "--kinect needs the live sensor support: install libfreenect-dev and run with \
             `cargo run --release --features freenect --example scan -- --kinect ...`",
        ))
    }
}

pub(super) use imp::capture;
