//! Rotations drawn at random.

use glam::DQuat;
use rand::Rng;

/// A rotation drawn uniformly from SO(3) (Shoemake's method).
pub fn uniform_rotation(rng: &mut impl Rng) -> DQuat {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    DQuat::from_xyzw(a * (tau * u2).sin(), a * (tau * u2).cos(), b * (tau * u3).sin(), b * (tau * u3).cos()).normalize()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::SampleStream;

    #[test]
    fn uniform_rotations_are_unbiased() {
        let mut rng = SampleStream::trajectory(1, "x", 0, "test");
        let n = 20000;
        let mean = (0..n).map(|_| uniform_rotation(&mut rng) * DVec3::Z).sum::<DVec3>() / n as f64;
        assert!(mean.length() < 0.03, "rotated axes average out: {mean}");
    }
}
