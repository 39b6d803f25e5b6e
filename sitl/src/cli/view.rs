//! The view's options, shared by `sitl run` and `sitl scenario` ([`ViewArgs`]), and `sitl view FILE.ulg`,
//! which opens an autopilot's flight log in the same view.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use sitl::view::{Delivery, Viewer, ViewerKind, ViewerOptions};

/// Options of the live view (Rerun; docs/view.md).
#[derive(Args, Clone, Debug)]
pub(crate) struct ViewArgs {
    /// Show the flight in Rerun as it flies: `auto` (the native viewer when there is a display, else the
    /// web viewer, whose address is printed), `web`, `native`, or `none` (only `--record`). Needs Python
    /// with rerun-sdk and aco_gcs (the repository's .venv, or SITL_VIEW_PYTHON).
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "auto", value_name = "VIEWER")]
    pub(crate) view: Option<ViewerKind>,
    /// The web viewer's HTTP port.
    #[arg(long, default_value_t = 9090, value_name = "PORT")]
    pub(crate) view_web_port: u16,
    /// Rerun's gRPC port, which viewers connect to (`rerun --connect rerun+http://127.0.0.1:PORT/proxy`).
    #[arg(long, default_value_t = 9876, value_name = "PORT")]
    pub(crate) view_grpc_port: u16,
    /// Save what the view shows to FILE, in Rerun's format (.rrd; `rerun FILE` opens it). Alone, records
    /// without a viewer.
    #[arg(long, value_name = "FILE")]
    pub(crate) record: Option<PathBuf>,
}

impl ViewArgs {
    /// The viewer to start, if any (`--view`, or `--record` alone: no viewer).
    pub(crate) fn options(&self) -> Result<Option<ViewerOptions>> {
        if let Some(path) = &self.record
            && path.extension().is_none_or(|e| e != "rrd")
        {
            bail!("--record {}: a recording is a Rerun .rrd file; name it FILE.rrd", path.display());
        }
        let kind = match (self.view, &self.record) {
            (None, None) => return Ok(None),
            (None, Some(_)) => ViewerKind::None,
            (Some(kind), _) => kind,
        };
        if kind == ViewerKind::None && self.record.is_none() {
            bail!("--view none shows nothing: add --record FILE.rrd");
        }
        Ok(Some(ViewerOptions {
            kind,
            web_port: self.view_web_port,
            grpc_port: self.view_grpc_port,
            record: self.record.clone(),
            // Without a viewer the bridge writes the recording and is done.
            exit_at_eof: kind == ViewerKind::None,
            ulog: None,
        }))
    }
}

/// Starts the view of `what` and says where it is. From here Ctrl-C (which reaches the bridge too, and
/// ends it cleanly) no longer ends this process at once, so it reports and exits as after a run.
pub(crate) fn start_viewer(opts: &ViewerOptions, delivery: Delivery, what: &str) -> Result<Viewer> {
    let stop = sitl::launch::ctrl_c_flag();
    let viewer = Viewer::start(opts, delivery)?;
    drop(stop);
    eprintln!("sitl: the view of {what}: {}", viewer.url);
    Ok(viewer)
}

/// Ends the view: the stream closed, then (a served web view) until Ctrl-C. The bridge says that it
/// keeps serving (a Ctrl-C that ended the run has ended it too).
pub(crate) fn finish_viewer(viewer: Viewer, opts: &ViewerOptions) -> Result<()> {
    let report = viewer.finish()?;
    if report.dropped > 0 {
        eprintln!("sitl: the view fell behind and dropped {} of {} frames", report.dropped, report.written);
    }
    if let Some(path) = &opts.record {
        eprintln!("sitl: recorded {} frames to {}", report.written, path.display());
    }
    Ok(())
}

#[derive(Args)]
pub(crate) struct ViewFileArgs {
    /// An autopilot ULog flight log (`.ulg`, from the state directory's log/<date>/), or a Rerun
    /// recording (`.rrd`, from `--record`).
    pub(crate) file: PathBuf,
    #[command(flatten)]
    pub(crate) view: ViewArgs,
}

/// `sitl view FILE`: a ULog in the view (the estimate, setpoints, motors, battery, ACO weights, modes and
/// messages; a flight log has no truth), or a recording handed to Rerun's viewer.
pub(crate) fn view(args: &ViewFileArgs) -> Result<()> {
    if !args.file.is_file() {
        bail!("{}: no such file", args.file.display());
    }
    let ext = args.file.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext != "ulg" {
        bail!(
            "{}: `sitl view` opens ULog flight logs (.ulg); open a recording with `rerun FILE.rrd`",
            args.file.display()
        );
    }
    let mut opts = args.view.options()?.unwrap_or_default();
    opts.ulog = Some(args.file.clone());
    let viewer = start_viewer(&opts, Delivery::Complete, &args.file.display().to_string())?;
    finish_viewer(viewer, &opts)
}
