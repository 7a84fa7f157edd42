//! The interactive viewer (`whitted view`): a window showing the scene rendered
//! progressively, a coarse preview first, then finer passes while nothing changes.
//!
//! Everything but the window itself is display-free: [`state`] turns keys into
//! changes, [`worker`] renders on its own thread and cancels stale work, [`reload`]
//! watches the scene's files, [`overlay`] draws the picture and the text.

pub mod overlay;
pub mod reload;
pub mod state;
pub mod worker;
