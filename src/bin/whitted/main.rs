//! The `whitted` command line: argument parsing, progress and messages. The rendering
//! itself lives in the library.

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};
use whitted::film::PendingOutput;
use whitted::render::Renderer;
use whitted::scene::{self, MAX_RESOLUTION, Scene};

#[derive(Parser)]
#[command(name = "whitted", version, about = "A fast recursive (Whitted-style) ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to a PNG file.
    Render(RenderArgs),
    /// Show a scene in a window, refined progressively and reloaded when its file
    /// changes. Keys: h lists them.
    View(ViewArgs),
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Scene file (TOML), reloaded when it or a file it names changes. Without one, the
    /// built-in seed room (give scenes/room.toml to edit it live).
    scene: Option<PathBuf>,
    /// Window width in pixels (default: the scene camera's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION), requires = "height")]
    width: Option<u32>,
    /// Window height in pixels (default: the scene camera's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION), requires = "width")]
    height: Option<u32>,
    /// Print to stderr when each pass reaches the screen and when full quality does
    /// (also on with WHITTED_TIMING=1).
    #[arg(long)]
    timing: bool,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file (TOML). Without one, the built-in seed room (scenes/room.toml).
    scene: Option<PathBuf>,
    /// Output PNG; by default the scene's name with .png, in the current folder.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Image width in pixels (overrides the scene's camera).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION))]
    width: Option<u32>,
    /// Image height in pixels (overrides the scene's camera).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION))]
    height: Option<u32>,
    /// Samples per pixel: 1 is one ray through the pixel centre; a square (4, 9, 16...)
    /// a jittered grid; other counts are spread one per row and column (N-rooks).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Option<u32>,
    /// Maximum ray depth (the primary ray is 1).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    depth: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Print ray counts, render time and Mrays/s.
    #[arg(long)]
    stats: bool,
    /// No progress bar and no warnings.
    #[arg(short, long)]
    quiet: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::View(args) => view(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Loads the scene named on the command line, or the built-in one.
fn load_scene(path: Option<&Path>) -> Result<(Scene, String), String> {
    match path {
        Some(p) => {
            let scene = scene::load_file(p).map_err(|e| e.to_string())?;
            let stem = p
                .file_stem()
                .map_or("render".into(), |s| s.to_string_lossy().into_owned());
            Ok((scene, stem))
        }
        None => {
            let scene = scene::load_str(scene::DEFAULT_SCENE, scene::DEFAULT_SCENE_NAME, Path::new("scenes"))
                .map_err(|e| e.to_string())?;
            Ok((scene, "room".to_owned()))
        }
    }
}

fn view(args: ViewArgs) -> Result<(), String> {
    whitted::viewer::window::run(whitted::viewer::Options {
        scene: args.scene,
        size: args.width.zip(args.height),
        timing: args.timing || std::env::var_os("WHITTED_TIMING").is_some_and(|v| v == "1"),
        screenshot_dir: PathBuf::from("."),
    })
}

fn render(args: RenderArgs) -> Result<(), String> {
    let (scene, stem) = load_scene(args.scene.as_deref())?;
    if !args.quiet {
        for w in scene.warnings() {
            eprintln!("warning: {w}");
        }
    }
    let output = args.output.unwrap_or_else(|| PathBuf::from(format!("{stem}.png")));
    // Claim the output before rendering, so a bad path fails in milliseconds, not after.
    let pending = PendingOutput::create(&output).map_err(|e| e.to_string())?;

    let mut renderer = Renderer::new(&scene).map_err(|e| e.to_string())?;
    let (w, h) = (
        args.width.unwrap_or(scene.camera.width),
        args.height.unwrap_or(scene.camera.height),
    );
    renderer = renderer.size(w, h);
    if let Some(n) = args.spp {
        renderer = renderer.spp(n);
    }
    if let Some(d) = args.depth {
        renderer = renderer.max_depth(d);
    }
    if let Some(t) = args.threads {
        renderer = renderer.threads(t as usize);
    }

    let show_progress = !args.quiet && std::io::stderr().is_terminal();
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed} (eta {eta})").expect("valid template"),
    );
    let start = Instant::now();
    let progress = |done: usize, total: usize| {
        if !show_progress {
            return;
        }
        // Only renders that take a while get a bar; quick ones stay silent.
        if bar.is_hidden() && start.elapsed() > Duration::from_secs(1) && done < total {
            bar.set_length(total as u64);
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        bar.set_position(done as u64);
    };
    let out = renderer.render_with_progress(&progress);
    bar.finish_and_clear();

    pending.commit(&out.image).map_err(|e| e.to_string())?;
    if args.stats {
        let s = out.stats;
        let secs = out.elapsed.as_secs_f64();
        println!(
            "image       {} x {}, {} spp -> {}",
            out.image.width(),
            out.image.height(),
            out.spp,
            output.display()
        );
        println!(
            "rays        primary {}  shadow {}  reflection {}  refraction {}",
            s.primary, s.shadow, s.reflection, s.refraction
        );
        println!("total       {} rays", s.total());
        println!("render time {:.3} s", secs);
        println!("speed       {:.2} Mrays/s", s.total() as f64 / secs / 1e6);
    }
    Ok(())
}
