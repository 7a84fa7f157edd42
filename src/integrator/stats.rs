/// Rays traced, by kind. Each render tile counts into its own and the totals are summed,
/// so counting costs no synchronisation on the hot path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    pub primary: u64,
    pub shadow: u64,
    /// Mirror reflections, including total internal reflections.
    pub reflection: u64,
    /// Rays through transparent surfaces, bent or straight.
    pub refraction: u64,
}

impl RayStats {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }
}

impl std::ops::AddAssign for RayStats {
    fn add_assign(&mut self, o: RayStats) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
    }
}

impl RayStats {
    /// Counts a ray sent on from a hit.
    #[inline(always)]
    pub fn count(&mut self, sent: super::Sent) {
        match sent {
            super::Sent::Refracted => self.refraction += 1,
            super::Sent::Reflected | super::Sent::TotalInternalReflection => self.reflection += 1,
        }
    }
}
