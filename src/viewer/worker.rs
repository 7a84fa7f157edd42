//! The render thread: takes one job at a time, runs its passes (each on all cores through
//! the library's [`Renderer`]) and sends back every finished pass. Submitting a job
//! cancels the one in progress at once, so the window thread never waits on a render.

use super::state::Pass;
use crate::accel::AccelKind;
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::RayStats;
use crate::render::Renderer;
use crate::scene::Scene;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// One picture to make, in passes of increasing quality.
#[derive(Clone, Debug)]
pub struct Job {
    pub scene: Arc<Scene>,
    pub camera: Camera,
    pub accel: AccelKind,
    pub width: u32,
    pub height: u32,
    pub passes: Vec<Pass>,
}

/// A finished pass of a job.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The job's number, as [`Worker::submit`] returned it.
    pub job: u64,
    /// Index into the job's passes, and how many there are.
    pub pass: usize,
    pub passes: usize,
    pub divisor: u32,
    pub spp: u32,
    /// The size of the view this pass is for (the image is smaller by `divisor`).
    pub width: u32,
    pub height: u32,
    pub image: Image,
    pub stats: RayStats,
    /// Time to render this pass alone.
    pub elapsed: Duration,
    /// Time from the job's submission to the end of this pass.
    pub since_submit: Duration,
}

impl Frame {
    pub fn is_final(&self) -> bool {
        self.pass + 1 == self.passes
    }
}

struct Queued {
    id: u64,
    job: Job,
    cancel: Arc<AtomicBool>,
    submitted: Instant,
}

pub struct Worker {
    jobs: Option<Sender<Queued>>,
    frames: Receiver<Frame>,
    current: Option<Arc<AtomicBool>>,
    next_id: u64,
    thread: Option<JoinHandle<()>>,
}

impl Default for Worker {
    fn default() -> Self {
        Self::new()
    }
}

impl Worker {
    pub fn new() -> Self {
        let (job_tx, job_rx) = mpsc::channel::<Queued>();
        let (frame_tx, frame_rx) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("whitted-render".into())
            .spawn(move || run(job_rx, frame_tx))
            .expect("spawn the render thread");
        Worker { jobs: Some(job_tx), frames: frame_rx, current: None, next_id: 1, thread: Some(thread) }
    }

    /// Cancels the job in progress (if any) and queues `job`; returns its number.
    pub fn submit(&mut self, job: Job) -> u64 {
        self.cancel();
        let id = self.next_id;
        self.next_id += 1;
        let cancel = Arc::new(AtomicBool::new(false));
        self.current = Some(cancel.clone());
        let queued = Queued { id, job, cancel, submitted: Instant::now() };
        if let Some(tx) = &self.jobs {
            // The thread only ends when this sender is dropped, so the send succeeds.
            let _ = tx.send(queued);
        }
        id
    }

    /// Stops the job in progress, if any.
    pub fn cancel(&mut self) {
        if let Some(c) = self.current.take() {
            c.store(true, Ordering::Relaxed);
        }
    }

    /// The cancel flag of the job in progress (for tests and diagnostics).
    pub fn current_cancel_flag(&self) -> Option<Arc<AtomicBool>> {
        self.current.clone()
    }

    /// A finished pass, if one is waiting.
    pub fn try_recv(&self) -> Option<Frame> {
        self.frames.try_recv().ok()
    }

    /// Waits up to `timeout` for a finished pass.
    pub fn recv_timeout(&self, timeout: Duration) -> Option<Frame> {
        self.frames.recv_timeout(timeout).ok()
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.cancel();
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(jobs: Receiver<Queued>, frames: Sender<Frame>) {
    while let Ok(mut q) = jobs.recv() {
        // Only the newest job matters; the others were cancelled when it came.
        while let Ok(newer) = jobs.try_recv() {
            q = newer;
        }
        // One acceleration structure per job, shared by all its passes.
        let world = crate::accel::World::new(&q.job.scene, q.job.accel);
        for (i, pass) in q.job.passes.iter().enumerate() {
            let Some(frame) = render_pass(&q, &world, i, *pass) else {
                break;
            };
            if frames.send(frame).is_err() {
                return;
            }
        }
    }
}

fn render_pass(q: &Queued, world: &crate::accel::World, index: usize, pass: Pass) -> Option<Frame> {
    if q.cancel.load(Ordering::Relaxed) {
        return None;
    }
    let job = &q.job;
    let (w, h) = pass.size(job.width, job.height);
    let renderer =
        Renderer::new(&job.scene).and_then(|r| r.camera(job.camera)).ok()?.size(w, h).spp(pass.spp).accel(job.accel);
    let out = renderer.render_world_cancellable(world, &q.cancel)?;
    Some(Frame {
        job: q.id,
        pass: index,
        passes: job.passes.len(),
        divisor: pass.divisor,
        spp: out.spp,
        width: job.width,
        height: job.height,
        image: out.image,
        stats: out.stats,
        elapsed: out.elapsed,
        since_submit: q.submitted.elapsed(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{DEFAULT_SCENE, DEFAULT_SCENE_NAME, load_str};
    use crate::viewer::state::schedule;
    use std::path::Path;

    fn room() -> Arc<Scene> {
        Arc::new(load_str(DEFAULT_SCENE, DEFAULT_SCENE_NAME, Path::new("scenes")).unwrap())
    }

    fn job(scene: &Arc<Scene>, width: u32, height: u32, spp: u32) -> Job {
        Job {
            scene: scene.clone(),
            camera: scene.camera,
            accel: AccelKind::default(),
            width,
            height,
            passes: schedule(width, height, spp),
        }
    }

    #[test]
    fn passes_arrive_in_order_and_the_last_matches_a_plain_render() {
        let scene = room();
        let mut w = Worker::new();
        let id = w.submit(job(&scene, 160, 120, 4));
        let mut got = Vec::new();
        while got.len() < 3 {
            let f = w.recv_timeout(Duration::from_secs(20)).expect("a pass within 20 s");
            assert_eq!(f.job, id);
            got.push(f);
        }
        assert_eq!(got.iter().map(|f| (f.divisor, f.spp)).collect::<Vec<_>>(), [(4, 1), (1, 1), (1, 4)]);
        assert_eq!((got[0].image.width(), got[0].image.height()), (40, 30));
        assert!(got[2].is_final());
        let plain = Renderer::new(&scene).unwrap().size(160, 120).spp(4).render();
        assert_eq!(got[2].image, plain, "the viewer's final picture is the batch render's");
    }

    #[test]
    fn a_new_job_cancels_the_one_in_progress() {
        let scene = room();
        let mut w = Worker::new();
        // Far too much work to finish within the test: 1024 spp at 800 × 800.
        let slow = w.submit(job(&scene, 800, 800, 1024));
        let flag = w.current_cancel_flag().unwrap();
        // Let it get past its quick passes into the slow ones.
        let deadline = Instant::now() + Duration::from_secs(30);
        while let Some(f) = w.recv_timeout(Duration::from_secs(30)) {
            if f.pass == 1 || Instant::now() > deadline {
                break;
            }
        }
        let start = Instant::now();
        let fast = w.submit(job(&scene, 64, 48, 1));
        assert!(flag.load(Ordering::Relaxed), "the old job was told to stop");
        let f = w.recv_timeout(Duration::from_secs(10)).expect("the new job's frame");
        assert_eq!(f.job, fast, "no late frame of job {slow} arrives");
        assert!(start.elapsed() < Duration::from_secs(5), "{:?}", start.elapsed());
    }
}
