//! `whitted render --frames A..B`: the frames of an animation, in order, each to the
//! output pattern with its run of `#` replaced by the frame number, under one progress
//! bar. A frame where only the camera moved reuses the acceleration structure of the
//! frame before.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use whitted::accel::World;
use whitted::film::{OutputOptions, PendingOutput};
use whitted::scene::animation::MAX_FRAME;
use whitted::scene::{Animation, Loaded};

/// `A..B`, both included (`0..119` is 120 frames), as the issue and shell loops write it.
pub fn parse_range(text: &str) -> Result<(u32, u32), String> {
    let t = text.trim();
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|&n| n <= MAX_FRAME);
    match t.split_once("..").map(|(a, b)| (parse(a), parse(b.strip_prefix('=').unwrap_or(b)))) {
        Some((Some(a), Some(b))) if a <= b => Ok((a, b)),
        Some((Some(a), Some(b))) => Err(format!("the first frame comes after the last ({a} > {b})")),
        _ => Err(format!("expected FIRST..LAST, two whole numbers from 0 to {MAX_FRAME} such as 0..119 (got {t:?})")),
    }
}

/// `pattern` with the last run of `#` in its file name replaced by `frame`, zero-padded
/// to the run's length (`frame-####.png` → `frame-0007.png`); `None` if it has none.
pub fn frame_path(pattern: &Path, frame: u32) -> Option<PathBuf> {
    let name = pattern.file_name()?.to_str()?;
    let end = name.rfind('#')? + 1;
    let start = name[..end].trim_end_matches('#').len();
    let number = format!("{frame:0width$}", width = end - start);
    Some(pattern.with_file_name(format!("{}{number}{}", &name[..start], &name[end..])))
}

/// Renders frames `first..=last` of `loaded` (a scene without keys gives the same image
/// each frame). Frames outside the scene's own range are allowed: values hold there.
pub fn render_frames(
    args: &super::RenderArgs,
    loaded: &Loaded,
    pattern: &Path,
    (first, last): (u32, u32),
    start: Instant,
) -> Result<(), String> {
    let still = Animation::default();
    let anim = loaded.animation.as_ref().unwrap_or(&still);
    let color = super::color(args, &loaded.scene);
    let options = OutputOptions { color, bits: args.bits };
    // Claim the first file before rendering, so a bad folder or format fails at once.
    let path = |f| frame_path(pattern, f).unwrap_or_else(|| pattern.to_owned());
    let mut claimed = Some(PendingOutput::create_with(&path(first), options).map_err(|e| e.to_string())?);

    let count = (last - first) as u64 + 1;
    let show_progress = !args.quiet && std::io::stderr().is_terminal();
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("frame {msg} {bar:40} {percent:>3}% {elapsed} (eta {eta})")
            .expect("valid template"),
    );
    let (mut worlds, mut build, mut render, mut size) = (0, Duration::ZERO, Duration::ZERO, (0, 0));
    let mut frame = first;
    while frame <= last {
        let scene = anim.scene_at(&loaded.scene, frame).map_err(|e| e.to_string())?;
        // The frames from here on that can share this frame's acceleration structure.
        let mut end = frame;
        while end < last && !anim.needs_new_world(end, end + 1) {
            end += 1;
        }
        let renderer = super::renderer(args, &scene)?;
        let world = renderer.in_pool(|| World::new(&scene, args.accel.into()));
        (worlds, build) = (worlds + 1, build + world.build_time());
        for f in frame..=end {
            let pending = match claimed.take() {
                Some(p) => p,
                None => PendingOutput::create_with(&path(f), options).map_err(|e| e.to_string())?,
            };
            let camera = anim.camera_at(&scene.camera, f);
            let r = renderer.clone().camera(camera).map_err(|e| format!("frame {f}: {e}"))?;
            bar.set_message(format!("{f} ({} of {count})", f - first + 1));
            let before = (f - first) as u64;
            let progress = |done: usize, total: usize| {
                if !show_progress {
                    return;
                }
                // As for one frame: only runs that take a while get a bar.
                if bar.is_hidden() && start.elapsed() > Duration::from_secs(1) && (before < count - 1 || done < total) {
                    bar.set_length(count * total as u64);
                    bar.set_draw_target(ProgressDrawTarget::stderr());
                }
                bar.set_position(before * total as u64 + done as u64);
            };
            let out = r.render_world_with_progress(&world, &progress);
            pending.commit(&out.image).map_err(|e| e.to_string())?;
            render += out.elapsed;
            size = (out.image.width(), out.image.height());
        }
        frame = end + 1;
    }
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    if !args.quiet {
        let (w, h) = size;
        eprintln!(
            "wrote {count} frames, {} to {}: {w}x{h}, {secs:.2} s ({:.3} s per frame)",
            path(first).display(),
            path(last).display(),
            secs / count as f64
        );
    }
    if args.stats {
        println!("frames      {count} ({first} to {last}); acceleration structures built: {worlds}");
        println!("build time  {:.3} s in all", build.as_secs_f64());
        println!(
            "render time {:.4} s in all, {:.4} s per frame",
            render.as_secs_f64(),
            render.as_secs_f64() / count as f64
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_inclusive_and_checked() {
        assert_eq!(parse_range("0..119"), Ok((0, 119)));
        assert_eq!(parse_range("5..5"), Ok((5, 5)));
        assert_eq!(parse_range("3..=4"), Ok((3, 4)));
        assert!(parse_range("9..2").unwrap_err().contains("after the last"));
        for bad in ["7", "a..b", "-1..3", "0..", "..4", "0..2000000"] {
            assert!(parse_range(bad).unwrap_err().contains("FIRST..LAST"), "{bad}");
        }
    }

    #[test]
    fn the_run_of_hashes_becomes_the_padded_frame_number() {
        let p = |s: &str, f| frame_path(Path::new(s), f).map(|p| p.display().to_string());
        assert_eq!(p("out/frame-####.png", 7).as_deref(), Some("out/frame-0007.png"));
        assert_eq!(p("out/frame-####.png", 123456).as_deref(), Some("out/frame-123456.png"));
        assert_eq!(p("f#.png", 3).as_deref(), Some("f3.png"));
        assert_eq!(p("a##b###.exr", 42).as_deref(), Some("a##b042.exr"), "the last run");
        assert_eq!(p("#dir/frame.png", 1), None, "only the file name counts");
        assert_eq!(p("frame.png", 1), None);
    }
}
