//! Environment-map streams: where each frame's cube map comes from. Plain Rust (no Bevy), so the
//! fault handling and the memory behaviour are tested without a window; the Bevy
//! `EnvisStreamPlugin` is a thin wrapper that advances a stream once per app update.
//!
//! Sources: the built-in animated sky; one `.exr`/`.hdr` file; a directory of frames played at a
//! chosen rate (looping, decoded on a background thread, double-buffered: the decoder works on
//! frame k+1 while frame k is shown, and [`EnvStream::advance`] never waits for it); a carousel that
//! rotates and cross-fades a list of maps. Every new frame gets a new generation number, so
//! consumers rebuild only when the frame changed.
//!
//! Faults: a frame that cannot be read keeps the last good frame, is reported once (per file) in
//! [`EnvStream::take_messages`], and playback goes on. Frames of another resolution are resampled
//! to the stream's face size, so downstream buffers change only when the face size does.

use crate::envmap::load::{EnvSource, load_env};
use crate::envmap::resample::cube_from_fetch;
use crate::envmap::{CubeMap, SanitizeReport, sky};
use crate::error::{Error, Result};
use glam::{Quat, Vec3};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError, sync_channel};

/// Where frames come from.
#[derive(Clone, Debug, PartialEq)]
pub enum StreamSource {
    /// Built-in sky starting at `hours`, advancing `speed` hours per second while playing.
    Sky { hours: f32, speed: f32 },
    /// One file, static.
    File(PathBuf),
    /// Every `.exr` / `.hdr` file of a directory, in name order, at `fps` frames per second, looping.
    Sequence { dir: PathBuf, fps: f32 },
    /// A list of maps, each shown `period` seconds (rotating about +Y at `spin` radians per
    /// second), cross-faded over the last `fade` seconds into the next.
    Carousel {
        paths: Vec<PathBuf>,
        period: f32,
        fade: f32,
        spin: f32,
    },
}

impl StreamSource {
    /// `builtin:sky[:HOURS]`, a file, or a directory (a sequence at 24 fps).
    pub fn parse(s: &str) -> Result<Self> {
        match s.parse::<EnvSource>()? {
            EnvSource::Sky { hours } => Ok(StreamSource::Sky { hours, speed: 0.5 }),
            EnvSource::File(p) if p.is_dir() => Ok(StreamSource::Sequence { dir: p, fps: 24.0 }),
            EnvSource::File(p) => Ok(StreamSource::File(p)),
        }
    }
}

/// One decoded frame of a sequence, or why it could not be.
type Decoded = (usize, std::result::Result<Arc<CubeMap>, String>);

/// Background decoder of a frame directory: decodes frames in order, one ahead (a channel of
/// capacity 1), looping. Dropping it stops the thread.
struct SequenceDecoder {
    files: Vec<PathBuf>,
    // A Mutex only so the stream is `Sync` (a Bevy resource); one thread ever locks it.
    rx: std::sync::Mutex<Receiver<Decoded>>,
    _thread: std::thread::JoinHandle<()>,
}

impl SequenceDecoder {
    fn start(dir: &Path, face_size: usize) -> Result<Self> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| Error::file(dir, format!("cannot read the frame directory: {e}")))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("hdr"))
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(Error::file(dir, "no .exr or .hdr frames in this directory"));
        }
        let (tx, rx) = sync_channel::<Decoded>(1);
        let list = files.clone();
        let thread = std::thread::Builder::new()
            .name("envis-sequence-decoder".into())
            .spawn(move || {
                for i in (0..list.len()).cycle() {
                    let r = load_env(&EnvSource::File(list[i].clone()), face_size)
                        .map(|l| Arc::new(l.cube))
                        .map_err(|e| e.to_string());
                    if tx.send((i, r)).is_err() {
                        return; // the stream was dropped
                    }
                }
            })
            .map_err(|e| Error::invalid(format!("cannot start the decoder thread: {e}")))?;
        Ok(SequenceDecoder {
            files,
            rx: std::sync::Mutex::new(rx),
            _thread: thread,
        })
    }
}

/// Counters of a stream (shown in the demo's panel, used by the tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StreamStats {
    /// Frames made current (including the first).
    pub frames: u64,
    /// Frames that could not be read (each kept the last good frame).
    pub bad_frames: u64,
    /// Times a sequence frame was due but the decoder had not finished it (the old frame stayed).
    pub late: u64,
}

/// A stream of cube maps; see the module documentation.
pub struct EnvStream {
    source: StreamSource,
    face_size: usize,
    current: Arc<CubeMap>,
    generation: u64,
    /// Seconds of playback (advances only while playing).
    time: f64,
    pub playing: bool,
    /// Playback rate multiplier.
    pub speed: f32,
    /// Clamped texels of the current frame's load (files) — zero for generated frames.
    pub report: SanitizeReport,
    stats: StreamStats,
    messages: Vec<String>,
    reported: HashSet<PathBuf>,
    decoder: Option<SequenceDecoder>,
    /// Sequence: when the next frame is due (playback seconds).
    next_due: f64,
    carousel: Vec<CubeMap>,
    /// Last sky time / carousel state that produced `current`, to skip identical frames.
    last_key: Option<(i64, i64)>,
}

impl EnvStream {
    pub fn open(source: StreamSource, face_size: usize) -> Result<Self> {
        if face_size == 0 || face_size > 4096 {
            return Err(Error::invalid(format!(
                "face size {face_size} out of range 1..=4096"
            )));
        }
        let mut s = EnvStream {
            source: source.clone(),
            face_size,
            current: Arc::new(CubeMap::new(face_size)),
            generation: 0,
            time: 0.0,
            playing: true,
            speed: 1.0,
            report: SanitizeReport::default(),
            stats: StreamStats::default(),
            messages: Vec::new(),
            reported: HashSet::new(),
            decoder: None,
            next_due: 0.0,
            carousel: Vec::new(),
            last_key: None,
        };
        match &source {
            StreamSource::Sky { .. } => s.make_sky(),
            StreamSource::File(p) => s.open_file(p)?,
            StreamSource::Sequence { dir, fps } => s.open_sequence(dir, *fps)?,
            StreamSource::Carousel { paths, .. } => s.open_carousel(paths)?,
        }
        Ok(s)
    }

    /// A still map: its sanitising report is the stream's.
    fn open_file(&mut self, p: &Path) -> Result<()> {
        let l = load_env(&EnvSource::File(p.to_path_buf()), self.face_size)?;
        self.report = l.report;
        if l.report.total() > 0 {
            self.messages.push(format!("{}: {}", p.display(), l.report));
        }
        self.set_frame(Arc::new(l.cube));
        Ok(())
    }

    /// Start the sequence's decoder and wait for its first good frame.
    fn open_sequence(&mut self, dir: &Path, fps: f32) -> Result<()> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(Error::invalid(format!(
                "sequence rate {fps} fps must be > 0"
            )));
        }
        let d = SequenceDecoder::start(dir, self.face_size)?;
        // The first frame is worth waiting for (there is nothing to show before it); any
        // unreadable frames before the first good one are reported and skipped.
        loop {
            let (i, r) =
                d.rx.lock()
                    .expect("decoder channel")
                    .recv()
                    .map_err(|_| Error::file(dir, "frame decoder stopped"))?;
            match r {
                Ok(m) => {
                    self.set_frame(m);
                    break;
                }
                Err(e) => {
                    self.bad_frame(&d.files[i], &e);
                    if self.stats.bad_frames as usize >= d.files.len() {
                        return Err(Error::file(
                            dir,
                            format!("no frame of the sequence could be read (last: {e})"),
                        ));
                    }
                }
            }
        }
        self.next_due = 1.0 / fps as f64;
        self.decoder = Some(d);
        Ok(())
    }

    /// Load every map of the carousel up front (a bad one is an error before anything plays).
    fn open_carousel(&mut self, paths: &[PathBuf]) -> Result<()> {
        if paths.is_empty() {
            return Err(Error::invalid("carousel: no maps given"));
        }
        for p in paths {
            self.carousel
                .push(load_env(&EnvSource::File(p.clone()), self.face_size)?.cube);
        }
        self.make_carousel();
        Ok(())
    }

    pub fn source(&self) -> &StreamSource {
        &self.source
    }
    pub fn face_size(&self) -> usize {
        self.face_size
    }
    /// The current frame.
    pub fn frame(&self) -> &Arc<CubeMap> {
        &self.current
    }
    /// Increases by one with every new frame.
    pub fn generation(&self) -> u64 {
        self.generation
    }
    pub fn stats(&self) -> StreamStats {
        self.stats
    }
    /// Playback time in seconds.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Sky: the current time of day.
    pub fn sky_hours(&self) -> Option<f32> {
        match self.source {
            StreamSource::Sky { hours, speed } => {
                Some((hours as f64 + self.time * speed as f64).rem_euclid(24.0) as f32)
            }
            _ => None,
        }
    }
    /// Sky: jump to a time of day.
    pub fn set_sky_hours(&mut self, h: f32) {
        if let StreamSource::Sky { hours, speed } = &mut self.source {
            *hours = h - (self.time * *speed as f64) as f32;
            self.make_sky();
        }
    }
    /// Messages (bad frames, clamped texels) since the last call.
    pub fn take_messages(&mut self) -> Vec<String> {
        std::mem::take(&mut self.messages)
    }

    /// Advance playback by `dt` seconds (times `speed`, if playing). Returns true when the frame
    /// changed. Never blocks.
    pub fn advance(&mut self, dt: f64) -> bool {
        let before = self.generation;
        if self.playing {
            self.time += dt.max(0.0) * self.speed as f64;
        }
        match self.source.clone() {
            StreamSource::Sky { .. } => self.make_sky(),
            StreamSource::File(_) => {}
            StreamSource::Sequence { fps, .. } => self.poll_sequence(fps as f64),
            StreamSource::Carousel { .. } => self.make_carousel(),
        }
        self.generation != before
    }

    fn set_frame(&mut self, m: Arc<CubeMap>) {
        self.current = m;
        self.generation += 1;
        self.stats.frames += 1;
    }

    fn bad_frame(&mut self, path: &Path, err: &str) {
        self.stats.bad_frames += 1;
        if self.reported.insert(path.to_path_buf()) {
            self.messages
                .push(format!("{err} (kept the last good frame)"));
        }
    }

    fn make_sky(&mut self) {
        let h = self.sky_hours().unwrap_or(12.0);
        // Regenerate only when the time of day moved by at least 1/1000 hour (3.6 s of sun).
        let key = ((h as f64 * 1000.0).round() as i64, 0);
        if self.last_key != Some(key) {
            self.last_key = Some(key);
            self.set_frame(Arc::new(sky::sky_cube(self.face_size, h)));
        }
    }

    /// At most one new frame per call: when updates fall behind the frame rate, frames are
    /// dropped (playback stays in real time) rather than consumed in a burst.
    fn poll_sequence(&mut self, fps: f64) {
        if self.time < self.next_due {
            return;
        }
        loop {
            let Some(d) = &self.decoder else { return };
            let got = d.rx.lock().expect("decoder channel").try_recv();
            match got {
                Ok((_, Ok(m))) => {
                    self.set_frame(m);
                    break;
                }
                Ok((i, Err(e))) => {
                    // Keep the last good frame; report once; go on to the next frame.
                    let path = d.files[i].clone();
                    self.bad_frame(&path, &e);
                }
                Err(TryRecvError::Empty) => {
                    // The decoder is behind: keep showing the current frame, try next update.
                    self.stats.late += 1;
                    return;
                }
                Err(TryRecvError::Disconnected) => {
                    self.messages
                        .push("frame decoder stopped; the last frame stays".into());
                    self.decoder = None;
                    return;
                }
            }
        }
        self.next_due += 1.0 / fps;
        if self.next_due <= self.time {
            self.next_due = self.time + 1.0 / fps;
        }
    }

    fn make_carousel(&mut self) {
        let StreamSource::Carousel {
            period, fade, spin, ..
        } = self.source.clone()
        else {
            return;
        };
        let n = self.carousel.len();
        let period = period.max(1e-3) as f64;
        let k = (self.time / period).floor();
        let a = (k as i64).rem_euclid(n as i64) as usize;
        let b = (a + 1) % n;
        let into = self.time - k * period;
        let fade = (fade as f64).clamp(0.0, period);
        let w = if fade > 0.0 {
            ((into - (period - fade)) / fade).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let w = (w * w * (3.0 - 2.0 * w)) as f32; // smoothstep
        let angle = (self.time * spin as f64) as f32;
        // Quantise to 1/1000 rad and 1/1000 of the fade so a paused carousel costs nothing.
        let key = (
            (angle as f64 * 1000.0).round() as i64,
            (k as i64) * 1000 + (w * 1000.0).round() as i64,
        );
        if self.last_key == Some(key) {
            return;
        }
        self.last_key = Some(key);
        let rot = Quat::from_rotation_y(-angle);
        let (ma, mb) = (&self.carousel[a], &self.carousel[b]);
        let m = cube_from_fetch(self.face_size, 1, |d: Vec3| {
            let r = rot * d;
            let x = ma.lookup(r);
            if w > 0.0 {
                x * (1.0 - w) + mb.lookup(r) * w
            } else {
                x
            }
        });
        self.set_frame(Arc::new(m));
    }
}
