//! Mutation test of the scene readers: the project's scene, NFF and OBJ files, mutated
//! by a seeded generator (byte flips, truncation, huge and odd numbers, deep nesting,
//! repeated lines), each loaded and, when it loads, rendered at 8x8 in this process.
//! Every case must end in an image or an error, never a panic. Bounded to about 30
//! seconds (WHITTED_MUTATION_SECS changes that; the seed is printed on failure).

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::{Duration, Instant};
use whitted::render::Renderer;
use whitted::scene::{self, Scene};

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const ODD_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1e300",
    "-1e39",
    "nan",
    "inf",
    "4294967296",
    "18446744073709551616",
    "1e-45",
    "3.4e38",
    "99999999999999999999999",
    "0x10",
    "1_000",
    "-2147483649",
    "16384",
    "65536",
    "1000",
];

fn mutate(src: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = src.to_vec();
    for _ in 0..1 + rng.below(3) {
        match rng.below(7) {
            0 if !v.is_empty() => {
                let i = rng.below(v.len());
                v[i] ^= 1 << rng.below(8);
            }
            1 if !v.is_empty() => v.truncate(rng.below(v.len())),
            2 | 3 => {
                // Replace a number with an odd one.
                let starts: Vec<usize> = (0..v.len())
                    .filter(|&i| v[i].is_ascii_digit() && (i == 0 || !v[i - 1].is_ascii_alphanumeric()))
                    .collect();
                if let Some(&s) = starts.get(rng.below(starts.len())) {
                    let e = (s..v.len()).find(|&i| !(v[i].is_ascii_digit() || v[i] == b'.')).unwrap_or(v.len());
                    let odd = ODD_NUMBERS[rng.below(ODD_NUMBERS.len())].as_bytes();
                    v.splice(s..e, odd.iter().copied());
                }
            }
            4 => {
                let depth = 1 + rng.below(5000);
                let at = rng.below(v.len() + 1);
                let nest: Vec<u8> = std::iter::repeat_n(b'[', depth).chain(std::iter::repeat_n(b']', depth)).collect();
                v.splice(at..at, nest);
            }
            5 if !v.is_empty() => {
                // Repeat a slice of the file.
                let a = rng.below(v.len());
                let b = (a + rng.below(200)).min(v.len());
                let copy = v[a..b].to_vec();
                for _ in 0..rng.below(50) {
                    v.splice(b..b, copy.iter().copied());
                }
            }
            _ => {
                let at = rng.below(v.len() + 1);
                let junk: Vec<u8> = (0..rng.below(16)).map(|_| rng.next() as u8).collect();
                v.splice(at..at, junk);
            }
        }
    }
    v
}

fn render_small(scene: &Scene) {
    if let Ok(r) = Renderer::new(scene) {
        let image = r.size(8, 8).spp(1).threads(1).render();
        assert_eq!((image.width(), image.height()), (8, 8));
    }
}

/// Loads (and renders) one mutated input; `Err` only for a panic.
fn run_case(kind: &str, bytes: &[u8], base: &Path) -> std::thread::Result<()> {
    catch_unwind(AssertUnwindSafe(|| match kind {
        "toml" => {
            if let Ok(text) = std::str::from_utf8(bytes)
                && let Ok(scene) = scene::load_str(text, "mutated.toml", base)
            {
                render_small(&scene);
            }
        }
        "nff" => {
            if let Ok(n) = scene::nff::read_nff(std::io::Cursor::new(bytes), "mutated.nff") {
                render_small(&n.scene);
            }
        }
        _ => {
            let _ = scene::obj::read_obj(std::io::Cursor::new(bytes), "mutated.obj", true);
        }
    }))
}

#[test]
fn mutated_inputs_end_in_an_image_or_an_error() {
    let mut inputs: Vec<(String, String, Vec<u8>)> = Vec::new();
    for (dir, ext) in [("tests/scenes/bad", "toml"), ("tests/scenes/bad_nff", "nff"), ("tests/scenes/bad_obj", "obj")] {
        for f in common::files_in(dir, ext) {
            inputs.push((ext.to_owned(), f.display().to_string(), std::fs::read(&f).unwrap()));
        }
    }
    for f in common::files_in("scenes", "toml").into_iter().chain(common::files_in("scenes", "nff")) {
        let ext = f.extension().unwrap().to_string_lossy().into_owned();
        inputs.push((ext, f.display().to_string(), std::fs::read(&f).unwrap()));
    }
    let secs = std::env::var("WHITTED_MUTATION_SECS").ok().and_then(|s| s.parse().ok()).unwrap_or(30);
    let deadline = Instant::now() + Duration::from_secs(secs);
    let base = common::manifest("tests/scenes/bad");
    // Panics are caught and counted; keep their messages off the test output.
    std::panic::set_hook(Box::new(|_| {}));
    let (mut cases, mut failures) = (0usize, Vec::new());
    let mut seed = 0x5eed_u64;
    while Instant::now() < deadline {
        seed += 1;
        let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let (kind, name, bytes) = &inputs[rng.below(inputs.len())];
        let mutated = mutate(bytes, &mut rng);
        cases += 1;
        if run_case(kind, &mutated, &base).is_err() {
            failures.push(format!("seed {seed}: {name} mutated panicked"));
        }
    }
    let _ = std::panic::take_hook();
    eprintln!("{cases} mutated inputs");
    assert!(cases > 50, "only {cases} cases ran");
    assert!(failures.is_empty(), "{} of {cases} panicked:\n{}", failures.len(), failures.join("\n"));
}
