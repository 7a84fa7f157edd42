//! The `whitted` command line: argument parsing, progress and messages. The rendering
//! itself lives in the library.

mod frames;
mod options;

use clap::{CommandFactory, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};
use whitted::accel::AccelKind;
use whitted::film::{ColorEncoding, OutputOptions, PendingOutput};
use whitted::render::Renderer;
use whitted::scene::{self, Loaded, MAX_RESOLUTION, Scene};

#[derive(Parser)]
#[command(name = "whitted", version, about = "A fast recursive (Whitted-style) ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image file (PNG, JPEG, OpenEXR or Radiance HDR).
    Render(RenderArgs),
    /// Measure ray rates, build time and memory on built-in scenes and meshes.
    Bench(BenchArgs),
    /// Show a scene in a window, refined progressively and reloaded when its file
    /// changes. Keys: h lists them.
    View(ViewArgs),
    /// Write a scene (TOML, NFF, OBJ or glTF) as the project's TOML, to edit it with the
    /// full format.
    Convert(ConvertArgs),
    /// Write a procedural test scene: the SPD sphereflake, as NFF.
    Generate(GenerateArgs),
}

#[derive(clap::Args)]
struct ConvertArgs {
    /// Scene to read: TOML, NFF, OBJ or glTF (by extension, or --format).
    input: PathBuf,
    /// TOML file to write (replaced whole, or left alone if anything fails).
    #[arg(value_name = "OUTPUT", required_unless_present = "output", conflicts_with = "output")]
    to: Option<PathBuf>,
    /// The TOML file to write, given as `render` and `generate` take theirs.
    #[arg(short, long, value_name = "OUTPUT")]
    output: Option<PathBuf>,
    /// Input format, instead of guessing from the extension.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// No warnings.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct GenerateArgs {
    /// What to generate.
    #[arg(value_enum)]
    what: Generated,
    /// Recursion level: 4 gives the SPD's 7,381 spheres, 6 gives 597,871.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=8))]
    level: u32,
    /// NFF file to write.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Generated {
    /// Eric Haines' sphereflake ("balls" in the SPD).
    Sphereflake,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Run only this built-in scene (room, spheres-1000, spheres-10000, spheres-100000,
    /// spheres-1000000, cubesphere-1M, and on request cubesphere-10M, sphere-cloud-1M); repeatable.
    #[arg(long)]
    scene: Vec<String>,
    /// Also measure this OBJ mesh (flat-shaded, framed like the Embree benchmark); repeatable.
    #[arg(long)]
    mesh: Vec<PathBuf>,
    /// Which structures: bvh, none, or both (none only where it finishes in reasonable
    /// time: scenes of at most 100 primitives, unless asked for alone).
    #[arg(long, default_value = "both", value_parser = ["bvh", "none", "both"])]
    accel: String,
    /// Timed runs per figure; the median is reported.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true, value_parser = options::count::<1000>)]
    runs: u32,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<1024>)]
    threads: Option<u32>,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Scene file: TOML, NFF, OBJ or glTF (.gltf, .glb), by extension; reloaded when it
    /// or a file it names changes. Without one, the built-in seed room (give
    /// scenes/room.toml to edit it live).
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
    /// Scene file: TOML, NFF, OBJ or glTF (.gltf, .glb), by extension or --format.
    /// Without one, the built-in seed room (scenes/room.toml).
    scene: Option<PathBuf>,
    /// Scene format, instead of guessing from the extension.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Output image: .png, .jpg, .exr or .hdr; by default the scene's name with .png,
    /// in the current folder. With --frames, a pattern whose run of # becomes the
    /// zero-padded frame number (out/frame-####.png; by default NAME-####.png).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Render the frames FIRST to LAST, both included (0..119 is 120 frames), of an
    /// animated scene (keys in its TOML), in order. Frames outside the scene's
    /// `[settings] frames` are allowed: every value holds beyond its keys.
    #[arg(long, value_name = "FIRST..LAST", value_parser = frames::parse_range, conflicts_with = "frame")]
    frames: Option<(u32, u32)>,
    /// Render frame N of an animated scene (default: the first of its `[settings] frames`);
    /// a run of # in the output name becomes the frame number.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=scene::animation::MAX_FRAME as i64))]
    frame: Option<u32>,
    /// How PNG and JPEG files encode colour (default: the scene's `[settings] color`,
    /// else linear). EXR and HDR are always linear.
    #[arg(long, value_parser = ["linear", "srgb"])]
    color: Option<String>,
    /// Bits per channel: PNG 8 (default) or 16, EXR 16 (half float, default) or 32.
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=32))]
    bits: Option<u32>,
    /// Image width in pixels (default: the scene camera's; alone, the height follows
    /// the camera's aspect ratio).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<{ MAX_RESOLUTION as u32 }>)]
    width: Option<u32>,
    /// Image height in pixels (default: the scene camera's; alone, the width follows
    /// the camera's aspect ratio).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<{ MAX_RESOLUTION as u32 }>)]
    height: Option<u32>,
    /// Multiplies the image size, e.g. 0.5 for a quick preview at half the width and height.
    #[arg(long, allow_negative_numbers = true, value_parser = options::scale)]
    scale: Option<f64>,
    /// Samples per pixel: 1 is one ray through the pixel centre; a square (4, 9, 16...)
    /// a jittered grid; other counts are spread one per row and column (N-rooks).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<65536>)]
    spp: Option<u32>,
    /// Maximum ray depth (the primary ray is 1).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<1000>)]
    depth: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = options::count::<1024>)]
    threads: Option<u32>,
    /// Acceleration structure: a bounding volume hierarchy, or none (test every object).
    #[arg(long, value_enum, default_value_t = Accel::Bvh)]
    accel: Accel,
    /// The testing procedure of Eric Haines' Standard Procedural Databases, for timings
    /// comparable with those published for other tracers: ray depth 5, one eye ray
    /// through each pixel corner (513 x 513 for 512 x 512) averaged four to a pixel,
    /// opaque surfaces one-sided, no shadow ray when the normal faces away from a light.
    #[arg(long, conflicts_with_all = ["spp", "depth"])]
    spd_rules: bool,
    /// Render only the pixels X0..X1 by Y0..Y1 (X1, Y1 exclusive) of the image and write
    /// just that part, exactly as it is in the full image: a batch system can split a
    /// frame across machines.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_region)]
    region: Option<[u32; 4]>,
    /// Print ray counts, render time and Mrays/s.
    #[arg(long)]
    stats: bool,
    /// No progress bar, no warnings and no line when done.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Format {
    Toml,
    Nff,
    Obj,
    Gltf,
}

impl Format {
    /// The format asked for, or the one the file's extension names.
    fn resolve(asked: Option<Format>, path: &Path) -> scene::Format {
        match asked {
            Some(Format::Toml) => scene::Format::Toml,
            Some(Format::Nff) => scene::Format::Nff,
            Some(Format::Obj) => scene::Format::Obj,
            Some(Format::Gltf) => scene::Format::Gltf,
            None => scene::Format::of_path(path),
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Accel {
    Bvh,
    None,
}

impl From<Accel> for AccelKind {
    fn from(a: Accel) -> AccelKind {
        match a {
            Accel::Bvh => AccelKind::Bvh,
            Accel::None => AccelKind::None,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // An interrupted render or conversion removes its unfinished output file.
    if let Err(e) = whitted::cleanup::remove_on_interrupt() {
        eprintln!("warning: {e}");
    }
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Bench(args) => bench(args),
        Command::View(args) => view(args),
        Command::Convert(args) => convert(args),
        Command::Generate(args) => generate(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Loads the scene named on the command line, or the built-in one; also gives the name
/// for the default output file.
fn load_scene(path: Option<&Path>, format: Option<Format>) -> Result<(Loaded, String), String> {
    match path {
        Some(p) => {
            let loaded = scene::load_path(p, Format::resolve(format, p)).map_err(|e| e.to_string())?;
            let stem = p.file_stem().map_or("render".into(), |s| s.to_string_lossy().into_owned());
            Ok((loaded, stem))
        }
        None => {
            let scene = scene::load_str(scene::DEFAULT_SCENE, scene::DEFAULT_SCENE_NAME, Path::new("scenes"))
                .map_err(|e| e.to_string())?;
            Ok((
                Loaded { scene, warnings: Vec::new(), notes: Vec::new(), nff: None, animation: None },
                "room".to_owned(),
            ))
        }
    }
}

#[cfg(feature = "viewer")]
fn view(args: ViewArgs) -> Result<(), String> {
    whitted::viewer::window::run(whitted::viewer::Options {
        scene: args.scene,
        size: args.width.zip(args.height),
        timing: args.timing || std::env::var_os("WHITTED_TIMING").is_some_and(|v| v == "1"),
        screenshot_dir: PathBuf::from("."),
    })
}

#[cfg(not(feature = "viewer"))]
fn view(_: ViewArgs) -> Result<(), String> {
    Err("this whitted was built without the viewer (cargo feature `viewer`, on by default): \
         rebuild with `cargo build --release --features viewer`"
        .to_owned())
}

/// The colour encoding of 8- and 16-bit files: `--color`, else the scene's.
fn color(args: &RenderArgs, scene: &Scene) -> ColorEncoding {
    args.color.as_deref().and_then(ColorEncoding::parse).unwrap_or(scene.settings.color)
}

/// A renderer of `scene` with the command line's size and sampling; its threads are
/// those of the pool [`render`] runs on.
fn renderer<'s>(args: &RenderArgs, scene: &'s Scene) -> Result<Renderer<'s>, String> {
    let mut renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    let camera = (scene.camera.width, scene.camera.height);
    let (w, h) = options::image_size(camera, args.width, args.height, args.scale, MAX_RESOLUTION as u32)?;
    renderer = renderer.size(w, h).accel(args.accel.into());
    if let Some(n) = args.spp {
        renderer = renderer.spp(n);
    }
    if let Some(d) = args.depth {
        renderer = renderer.max_depth(d);
    }
    if args.spd_rules {
        renderer = renderer.spd_rules();
    }
    if let Some([x0, y0, x1, y1]) = args.region {
        renderer = renderer.region(x0, y0, x1, y1).map_err(|e| format!("--region: {e}"))?;
    }
    Ok(renderer)
}

/// Renders on a pool of `--threads` threads (all cores by default), made once: the
/// scene's reading (a big NFF file in chunks), the build and the render share it.
fn render(args: RenderArgs) -> Result<(), String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.map_or(0, |t| t as usize))
        .build()
        .map_err(|e| format!("cannot start the worker threads: {e}"))?;
    pool.install(|| render_on_pool(args))
}

fn render_on_pool(args: RenderArgs) -> Result<(), String> {
    let stem = args
        .scene
        .as_deref()
        .map_or("room".into(), |p| p.file_stem().map_or("render".into(), |s| s.to_string_lossy().into_owned()));
    let hashes = if args.frames.is_some() { "-####" } else { "" };
    let output = args.output.clone().unwrap_or_else(|| PathBuf::from(format!("{stem}{hashes}.png")));
    if args.frames.is_some() && frames::frame_path(&output, 0).is_none() {
        let message = format!(
            "--frames needs an output name with a run of # for the frame number, such as out/frame-####.png (got {})",
            output.display()
        );
        let mut cli = Cli::command();
        cli.build();
        let render = cli.find_subcommand_mut("render").expect("the render subcommand exists");
        render.error(clap::error::ErrorKind::ArgumentConflict, message).exit();
    }
    let load_start = Instant::now();
    let (loaded, _) = load_scene(args.scene.as_deref(), args.format)?;
    let load_time = load_start.elapsed();
    if !args.quiet {
        for w in loaded.warnings.iter().chain(&loaded.scene.warnings()) {
            eprintln!("warning: {w}");
        }
        for n in &loaded.notes {
            eprintln!("note: {n}");
        }
    }
    if let Some(range) = args.frames {
        return frames::render_frames(&args, &loaded, &output, range, load_start);
    }
    // One frame: the one asked for, else an animation's first.
    let frame = args.frame.or(loaded.animation.as_ref().map(|a| a.first));
    let at_frame;
    let scene = match (&loaded.animation, frame) {
        (Some(anim), Some(f)) => {
            if args.frame.is_none() && !args.quiet {
                eprintln!(
                    "note: the scene is animated (frames {0}..{1}): rendering frame {0}; --frames {0}..{1} renders them all",
                    anim.first, anim.last
                );
            }
            at_frame = anim.scene_at(&loaded.scene, f).map_err(|e| e.to_string())?;
            &at_frame
        }
        _ => &loaded.scene,
    };
    let output = frame.and_then(|f| frames::frame_path(&output, f)).unwrap_or(output);
    // Claim the output before rendering, so a bad path fails in milliseconds, not after.
    let pending = PendingOutput::create_with(&output, OutputOptions { color: color(&args, scene), bits: args.bits })
        .map_err(|e| e.to_string())?;

    let renderer = renderer(&args, scene)?;
    let camera = (scene.camera.width, scene.camera.height);
    let (w, h) = options::image_size(camera, args.width, args.height, args.scale, MAX_RESOLUTION as u32)?;
    let bytes = options::image_bytes(w, h);
    if !args.quiet && bytes > 1 << 30 {
        eprintln!(
            "warning: a {w}x{h} image needs about {:.1} GiB of memory (its film and the PNG being written)",
            bytes as f64 / (1u64 << 30) as f64
        );
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
    if !args.quiet {
        let (w, h) = (out.image.width(), out.image.height());
        let samples = if out.corners { "corner sampling".to_owned() } else { format!("{} spp", out.spp) };
        eprintln!("wrote {}: {w}x{h}, {samples}, {:.2} s", output.display(), load_start.elapsed().as_secs_f64());
    }
    if args.stats {
        let s = out.stats;
        let secs = out.elapsed.as_secs_f64();
        let (w, h) = (out.image.width(), out.image.height());
        if out.corners {
            println!("image       {w} x {h}, corner sampling ({} x {} eye rays) -> {}", w + 1, h + 1, output.display());
        } else {
            println!("image       {w} x {h}, {} spp -> {}", out.spp, output.display());
        }
        println!(
            "rays        primary {}  shadow {}  reflection {}  refraction {}",
            s.primary, s.shadow, s.reflection, s.refraction
        );
        println!("total       {} rays", s.total());
        println!("load time   {:.4} s (parse and check the scene)", load_time.as_secs_f64());
        if let Some(n) = &loaded.nff {
            let secs = load_time.as_secs_f64().max(1e-9);
            println!(
                "nff         {} lines, {:.1} MB, {:.0} MB/s: {} spheres, {} cones and cylinders, {} polygons and {} patches as {} triangles and {} parallelograms",
                n.lines,
                n.bytes as f64 / 1e6,
                n.bytes as f64 / 1e6 / secs,
                n.spheres,
                n.cones,
                n.polygons,
                n.patches,
                n.triangles,
                n.quads
            );
        }
        println!(
            "build time  {:.4} s ({} acceleration structure)",
            out.build_time.as_secs_f64(),
            AccelKind::from(args.accel).name()
        );
        println!("render time {:.4} s", secs);
        println!("speed       {:.2} Mrays/s", s.total() as f64 / secs / 1e6);
    }
    Ok(())
}

/// `X0,Y0,X1,Y1` as four pixel coordinates.
fn parse_region(s: &str) -> Result<[u32; 4], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let nums: Option<Vec<u32>> = parts.iter().map(|p| p.parse().ok()).collect();
    match nums.as_deref() {
        Some(&[x0, y0, x1, y1]) => Ok([x0, y0, x1, y1]),
        _ => Err(format!("expected X0,Y0,X1,Y1 (four whole numbers of pixels), got {s:?}")),
    }
}

fn convert(args: ConvertArgs) -> Result<(), String> {
    let Some(output) = args.to.or(args.output) else {
        return Err("give the TOML file to write: whitted convert IN OUT.toml (or -o OUT.toml)".into());
    };
    let is_toml = output.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if !is_toml {
        return Err(format!("{}: only TOML output is supported (give the file a .toml extension)", output.display()));
    }
    let loaded = scene::load_path(&args.input, Format::resolve(args.format, &args.input)).map_err(|e| e.to_string())?;
    if !args.quiet {
        for w in loaded.warnings.iter().chain(&loaded.scene.warnings()) {
            eprintln!("warning: {w}");
        }
        if let Some(a) = &loaded.animation {
            eprintln!("warning: the scene's keys are not written: the TOML holds frame {} of its animation", a.first);
        }
    }
    let note = format!("Converted from {} by whitted convert.", args.input.display());
    scene::save::save_toml(&loaded.scene, &note, &output).map_err(|e| match e {
        scene::save::SaveError::Io { source, .. } => format!("{}: cannot write: {source}", output.display()),
        other => format!("{}: {other}", args.input.display()),
    })
}

fn generate(args: GenerateArgs) -> Result<(), String> {
    match args.what {
        Generated::Sphereflake => {
            scene::save::write_atomically(&args.output, |w| scene::generate::sphereflake(args.level, w))
                .map_err(|e| format!("{}: cannot write: {e}", args.output.display()))
        }
    }
}

fn bench(args: BenchArgs) -> Result<(), String> {
    use whitted::bench::{BenchCase, run};
    let threads =
        args.threads.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |t| t as usize);
    // Check every name and file before spending minutes measuring.
    let names: Vec<String> = if args.scene.is_empty() && args.mesh.is_empty() {
        BenchCase::BUILTIN.iter().map(|s| s.to_string()).collect()
    } else {
        args.scene.clone()
    };
    let known = || BenchCase::BUILTIN.iter().chain(BenchCase::ON_REQUEST);
    if let Some(bad) = names.iter().find(|n| !known().any(|k| k == n)) {
        let all: Vec<&str> = known().copied().collect();
        return Err(format!("--scene {bad}: no such built-in scene (expected one of {})", all.join(", ")));
    }
    for m in &args.mesh {
        if !m.is_file() {
            return Err(format!("--mesh {}: no such file", m.display()));
        }
    }
    let mut cases: Vec<Box<dyn FnOnce() -> Result<BenchCase, String>>> = Vec::new();
    for n in names {
        cases.push(Box::new(move || Ok(BenchCase::builtin(&n).expect("checked above"))));
    }
    for m in args.mesh {
        cases.push(Box::new(move || BenchCase::obj(&m).map_err(|e| e.to_string())));
    }
    if !args.json {
        println!(
            "{:<22} {:>10} {:>5} {:>10} {:>10} {:>8} {:>9} {:>9} {:>11} {:>9}   per CPU-s: {:>7} {:>7} {:>7}",
            "scene",
            "prims",
            "accel",
            "build ms",
            "accel MB",
            "B/prim",
            "primary",
            "shadow",
            "incoherent",
            "frame ms",
            "prim",
            "shadow",
            "incoh"
        );
    }
    for make in cases {
        let case = make()?;
        let kinds: &[AccelKind] = match args.accel.as_str() {
            "bvh" => &[AccelKind::Bvh],
            "none" => &[AccelKind::None],
            _ if case.primitives <= 100 => &[AccelKind::Bvh, AccelKind::None],
            _ => &[AccelKind::Bvh],
        };
        for &kind in kinds {
            let row = run(&case, kind, args.runs as usize, threads);
            if args.json {
                println!("{}", serde_json::to_string(&row).map_err(|e| e.to_string())?);
            } else {
                println!(
                    "{:<22} {:>10} {:>5} {:>10.1} {:>10.2} {:>8.1} {:>9.2} {:>9.2} {:>11.2} {:>9.1}              {:>7.2} {:>7.2} {:>7.2}",
                    row.scene,
                    row.primitives,
                    row.accel,
                    row.build_ms,
                    row.accel_bytes as f64 / 1048576.0,
                    row.bytes_per_primitive,
                    row.primary_mrays,
                    row.shadow_mrays,
                    row.incoherent_mrays,
                    row.frame_ms,
                    row.primary_mrays_per_cpu_s,
                    row.shadow_mrays_per_cpu_s,
                    row.incoherent_mrays_per_cpu_s
                );
            }
        }
    }
    if !args.json {
        println!(
            "rays in Mrays/s (median of {} runs, {threads} threads); primary and shadow rays from 1024x1024 cameras (the room: 800x800)",
            args.runs
        );
    }
    Ok(())
}
