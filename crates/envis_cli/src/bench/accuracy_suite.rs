//! Suite `accuracy`'s driver: runs the sweep of [`super::accuracy`] with a progress bar and writes its
//! files.

use super::*;
use std::path::Path;

/// The sweep's progress on stderr (indicatif): on a terminal a bar redrawn in place, with the
/// count, the time so far, the time left and the rate; elsewhere (logs, CI) the same figures as a
/// plain line every 5%.
struct Progress {
    bar: indicatif::ProgressBar,
    tty: bool,
}

impl Progress {
    fn new(total: usize) -> Self {
        use std::io::IsTerminal;
        let tty = std::io::stderr().is_terminal();
        let bar = if tty {
            indicatif::ProgressBar::new(total as u64)
        } else {
            indicatif::ProgressBar::hidden()
        };
        bar.set_length(total as u64);
        let style = indicatif::ProgressStyle::with_template(
            "[{bar:30}] {pos}/{len} {percent:>3}%  {elapsed}, ~{eta} left, {per_sec}  {msg}",
        )
        .map(|s| s.progress_chars("#>."))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
        bar.set_style(style);
        Progress { bar, tty }
    }

    /// `done` points of the total finished, the last one described by `what`.
    fn update(&self, done: usize, what: &str) {
        self.bar.set_position(done as u64);
        self.bar.set_message(what.to_string());
        let total = self.bar.length().unwrap_or(0) as usize;
        if !self.tty && (done.is_multiple_of((total / 20).max(1)) || done == total) {
            eprintln!(
                "{done}/{total} {:3.0}%  {:.1} s, ~{:.1} s left, {:.1} points/s  {what}",
                100.0 * done as f64 / total.max(1) as f64,
                self.bar.elapsed().as_secs_f64(),
                self.bar.eta().as_secs_f64(),
                self.bar.per_sec()
            );
        }
        if done == total {
            self.bar.finish();
        }
    }
}

/// Suite `accuracy`: writes `accuracy.csv`, `accuracy.json` and `accuracy-vs-time.md` to `dir`.
pub(super) fn accuracy_suite(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let cfg = accuracy::Config::new(a.quick, a.maps.as_deref())?;
    let start = Instant::now();
    let total = accuracy::point_count(&cfg);
    eprintln!(
        "envis bench accuracy: {} environments x {} materials, {total} points",
        cfg.envs.len(),
        cfg.materials.len()
    );
    let gpu_ctx = gpu_backend(&a);
    let gpu_device = gpu_ctx
        .as_ref()
        .map(|c| format!("{} ({:?})", c.info.name, c.info.backend));

    // Resumable: every finished point is appended to `accuracy.partial.jsonl` (first line: the
    // sweep's fingerprint). A rerun with the same configuration takes those points and measures
    // only the rest; the file is removed once the outputs are written.
    let fingerprint = serde_json::to_string(&accuracy::fingerprint(&cfg, gpu_device.as_deref()))
        .map_err(|e| Error::invalid(format!("accuracy: {e}")))?;
    let partial = dir.join("accuracy.partial.jsonl");
    let resume = resumed_points(&partial, &fingerprint, total);
    let mut journal = Journal::open(&partial, &fingerprint, &resume)?;
    let mut progress: Option<Progress> = None;
    let report_progress = |done: usize, total: usize, p: &accuracy::Point, was_resumed: bool| {
        if !was_resumed {
            journal.append(p);
        }
        // Made on the first point: the sweep knows the total only then.
        let bar = progress.get_or_insert_with(|| Progress::new(total));
        bar.update(
            done,
            &format!("{} / {} / {} N={}", p.env, p.material, p.strategy, p.budget),
        );
    };
    let points = sweep_on(&cfg, &resume, gpu_ctx.as_ref(), report_progress)?;
    journal.warn_if_failed();
    let out = Outputs {
        dir: &dir,
        command: suite_command(&a),
        gpu_device: gpu_device.as_deref(),
        start,
        resumed: resume.len(),
    };
    out.write(&cfg, &points)?;
    let _ = std::fs::remove_file(&partial);
    Ok(())
}

/// The GPU backend, when this build has it and a device is there (`--cpu-only` skips it).
fn gpu_backend(a: &BenchArgs) -> Option<envis_wgpu::GpuContext> {
    if a.cpu_only {
        return None;
    }
    envis_wgpu::GpuContext::new()
        .map_err(|e| eprintln!("accuracy: no GPU backend ({e}); CPU only"))
        .ok()
}

/// [`accuracy::sweep`], each point also timed on `gpu` when there is one.
fn sweep_on(
    cfg: &accuracy::Config,
    resume: &[accuracy::Point],
    gpu: Option<&envis_wgpu::GpuContext>,
    progress: impl FnMut(usize, usize, &accuracy::Point, bool),
) -> Result<Vec<accuracy::Point>> {
    let Some(ctx) = gpu else {
        return accuracy::sweep(cfg, resume, None, progress);
    };
    let mut renderer = envis_wgpu::GpuRenderer::new(ctx);
    let mut time = |map: &CubeMap,
                    gbuf: &[Option<render::GPixel>],
                    size: usize,
                    s: &Settings|
     -> Result<(f64, f64)> {
        let (_, t) = renderer.render(map, gbuf, size, size, s)?;
        Ok((
            t.build_gpu_ms.unwrap_or(t.build_wall_ms),
            t.shade_gpu_ms.unwrap_or(t.shade_wall_ms),
        ))
    };
    accuracy::sweep(cfg, resume, Some(&mut time), progress)
}

/// The points an interrupted run of the same configuration (first line `fingerprint`) left in
/// `partial`; none if it is from another configuration or absent. A line cut short by the
/// interruption is dropped (and measured again).
fn resumed_points(partial: &Path, fingerprint: &str, total: usize) -> Vec<accuracy::Point> {
    let Ok(text) = std::fs::read_to_string(partial) else {
        return Vec::new();
    };
    let mut lines = text.lines();
    if lines.next() != Some(fingerprint) {
        eprintln!(
            "accuracy: {} is from a different configuration; starting over",
            partial.display()
        );
        return Vec::new();
    }
    let pts: Vec<accuracy::Point> = lines.filter_map(|l| serde_json::from_str(l).ok()).collect();
    eprintln!(
        "accuracy: resuming {} of {total} points from {}",
        pts.len(),
        partial.display()
    );
    pts
}

/// The resume journal: each measured point appended as a JSON line. A failed append is kept
/// (the first one) and only makes the run not resumable.
struct Journal<'a> {
    path: &'a Path,
    file: std::fs::File,
    error: Option<std::io::Error>,
}

impl<'a> Journal<'a> {
    /// `partial` rewritten with `fingerprint` and the `resume`d points, open for appending.
    fn open(partial: &'a Path, fingerprint: &str, resume: &[accuracy::Point]) -> Result<Self> {
        let mut text = format!("{fingerprint}\n");
        for p in resume {
            text += &(serde_json::to_string(p).unwrap() + "\n");
        }
        std::fs::write(partial, text)
            .map_err(|e| Error::file(partial, format!("cannot write: {e}")))?;
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(partial)
            .map_err(|e| Error::file(partial, format!("cannot append: {e}")))?;
        Ok(Journal {
            path: partial,
            file,
            error: None,
        })
    }

    /// Appends point `p`, keeping the error if that fails.
    fn append(&mut self, p: &accuracy::Point) {
        use std::io::Write as _;
        if let Err(e) = writeln!(self.file, "{}", serde_json::to_string(p).unwrap()) {
            self.error.get_or_insert(e);
        }
    }

    /// Says on stderr that the run is not resumable, if an append failed.
    fn warn_if_failed(&self) {
        if let Some(e) = &self.error {
            eprintln!(
                "accuracy: could not append to {} ({e}); this run is not resumable",
                self.path.display()
            );
        }
    }
}

/// The command line that reproduces this run, for the report.
fn suite_command(a: &BenchArgs) -> String {
    let mut command = String::from("envis bench --suite accuracy");
    if a.quick {
        command.push_str(" --quick");
    }
    if let Some(m) = &a.maps {
        command.push_str(&format!(" --maps {}", m.display()));
    }
    command
}

/// Where and how the suite's files are written.
struct Outputs<'a> {
    dir: &'a Path,
    command: String,
    gpu_device: Option<&'a str>,
    start: Instant,
    /// Points taken from an interrupted run.
    resumed: usize,
}

impl Outputs<'_> {
    fn file(&self, name: &str, text: String) -> Result<()> {
        let p = self.dir.join(name);
        std::fs::write(&p, text).map_err(|e| Error::file(&p, format!("cannot write: {e}")))
    }

    /// `accuracy.csv`, `accuracy.json`, the plots and `accuracy-vs-time.md`.
    fn write(&self, cfg: &accuracy::Config, points: &[accuracy::Point]) -> Result<()> {
        self.file("accuracy.csv", accuracy::csv(points))?;
        envis::render::output::write_json(
            &self.dir.join("accuracy.json"),
            &serde_json::json!({ "command": self.command, "points": points }),
        )?;
        let mut md = accuracy::report(cfg, points, &self.command, self.gpu_device);
        md.push_str(&self.plots(cfg, points)?);
        md.push_str(&format!(
            "Sweep time: {:.0} s{}.\n",
            self.start.elapsed().as_secs_f64(),
            if self.resumed > 0 {
                format!(
                    " ({} of {} points resumed from an interrupted run)",
                    self.resumed,
                    points.len()
                )
            } else {
                String::new()
            }
        ));
        self.file("accuracy-vs-time.md", md)?;
        eprintln!(
            "wrote accuracy.csv, accuracy.json, accuracy-vs-time.md to {} in {:.0} s",
            self.dir.display(),
            self.start.elapsed().as_secs_f64()
        );
        Ok(())
    }

    /// The plots (SVG and PNG) and the report's section showing them.
    fn plots(&self, cfg: &accuracy::Config, points: &[accuracy::Point]) -> Result<String> {
        let mut md = String::from("## Plots\n\n");
        md.push_str("Each plot is written as SVG and PNG (plotters); the PNGs are shown here.\n\n");
        for (mname, _) in &cfg.materials {
            let stem = accuracy::plot_stem(mname);
            let (_, time_png) =
                accuracy::plot_error_vs_time(points, mname).write(self.dir, &stem)?;
            let (_, samples_png) = accuracy::plot_error_vs_samples(points, mname)
                .write(self.dir, &format!("{stem}-samples"))?;
            md.push_str(&format!(
                "![{mname}: error vs time]({time_png}) ![{mname}: error vs samples]({samples_png})\n\n"
            ));
        }
        let (_, wasted_png) = accuracy::plot_wasted(points).write(self.dir, "accuracy-wasted")?;
        md.push_str(&format!("![wasted light samples]({wasted_png})\n\n"));
        Ok(md)
    }
}
