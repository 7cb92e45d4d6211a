//! Where a spatial plan's time goes: per phase of the planning loop, how many times it ran and
//! the time it took, summed over the threads that ran it (`icrflow plan --verbose`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;

/// One phase's count and time, kept by any thread.
#[derive(Debug, Default)]
pub struct Counter {
    count: AtomicU64,
    nanos: AtomicU64,
}

impl Counter {
    /// Runs `f`, counting it and its time.
    pub fn time<T>(&self, f: impl FnOnce() -> T) -> T {
        let started = Instant::now();
        let out = f();
        let nanos = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.count.fetch_add(1, Ordering::Relaxed);
        self.nanos.fetch_add(nanos, Ordering::Relaxed);
        out
    }

    /// What it counted.
    pub fn read(&self) -> PhaseTime {
        PhaseTime {
            count: self.count.load(Ordering::Relaxed),
            seconds: Duration::from_nanos(self.nanos.load(Ordering::Relaxed)).as_secs_f64(),
        }
    }
}

/// A phase's count and its time (s, summed over the threads that ran it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PhaseTime {
    /// How many times it ran.
    pub count: u64,
    /// Its time (s).
    pub seconds: f64,
}

/// The phases a spatial plan is timed in, as they run.
#[derive(Debug, Default)]
pub struct Timing {
    /// Rolling steps of every contact (the ICRs, the fingers' rolling, the checks).
    pub rolling: Counter,
    /// Switch searches (each whole, on the thread that asked).
    pub switches: Counter,
    /// Their exact rendezvous regions (every candidate's grasp with the remaining contacts).
    pub regions: Counter,
    /// Free fingers placed at a region's candidate (a centred inverse kinematics each; those
    /// out of the finger's reach map are passed without).
    pub placements: Counter,
    /// Placements' rolling room simulated.
    pub rooms: Counter,
    /// Placements checked (routes, grasps, a rolling step after); on several threads, those
    /// checked ahead in a batch past the one chosen count too (the count depends on the
    /// threads, the plan does not).
    pub checks: Counter,
    /// Of those checks, the approach and retreat routes (each check's once; not the retreat
    /// checked once per finger of a search without that finger).
    pub routes: Counter,
}

impl Timing {
    /// What it counted.
    pub fn read(&self) -> PhaseTimes {
        PhaseTimes {
            rolling: self.rolling.read(),
            switches: self.switches.read(),
            regions: self.regions.read(),
            placements: self.placements.read(),
            rooms: self.rooms.read(),
            checks: self.checks.read(),
            routes: self.routes.read(),
        }
    }
}

/// Where a spatial plan's time went ([`Timing`] read).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PhaseTimes {
    /// See [`Timing::rolling`].
    pub rolling: PhaseTime,
    /// See [`Timing::switches`].
    pub switches: PhaseTime,
    /// See [`Timing::regions`].
    pub regions: PhaseTime,
    /// See [`Timing::placements`].
    pub placements: PhaseTime,
    /// See [`Timing::rooms`].
    pub rooms: PhaseTime,
    /// See [`Timing::checks`].
    pub checks: PhaseTime,
    /// See [`Timing::routes`].
    pub routes: PhaseTime,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_phase_is_counted_with_its_time_from_any_thread() {
        let c = Counter::default();
        let out = c.time(|| {
            std::thread::sleep(Duration::from_millis(2));
            7
        });
        assert_eq!(out, 7);
        std::thread::scope(|s| {
            for _ in 0..2 {
                s.spawn(|| c.time(|| std::thread::sleep(Duration::from_millis(1))));
            }
        });
        let t = c.read();
        assert_eq!(t.count, 3);
        assert!(t.seconds >= 0.004, "{t:?}");
    }
}
