//! The unilateral planes of a local model, rendered through a god-object proxy (Zilles and Salisbury, 1995).
//!
//! Owns: [`PlaneProxy`], the proxy position and the plane force. A plane is a half-space: the tool origin is
//! clear while `normal . x >= offset_mm`. The proxy is the point nearest the device that stays clear of every
//! plane it was clear of at the previous tick, so a device that jumps through a surface in one tick is still
//! pushed back out the side it came from, and a device pressed into a groove feels the full spring to the
//! groove's edge. Planes the proxy is already behind (a device that started inside, or a plane that arrived
//! above it) are not constraints: they push on the device position as plain penalties, so nothing is launched.
//!
//! Must not: allocate (fixed arrays of [`MAX_CONTACT_PLANES`]), clamp for safety, render the linear part
//! ([`super::local_model`]), or know about model switching ([`super::blend`]).

use sinew_protocol::messages::{ContactPlane, MAX_CONTACT_PLANES};

use super::{MAX_DRAG_PER_NORMAL, all_finite};

/// The proxy constrains itself to planes it was on or outside of within this distance, mm.
pub const CONSTRAINT_TOLERANCE_MM: f64 = 1e-4;

/// A proxy candidate counts as clear of a constraint plane within this distance, mm (f64 arithmetic leaves
/// ~1e-13 mm on a plane a candidate was projected onto).
const FEASIBLE_TOLERANCE_MM: f64 = 1e-6;

/// Subsets of constraint planes whose Gram determinant is below this are degenerate (parallel normals) and
/// skipped; a pair at 1e-9 is 3e-5 rad from parallel.
const MIN_GRAM_DETERMINANT: f64 = 1e-9;

type Vec3 = [f64; 3];

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn to_f64(v: [f32; 3]) -> Vec3 {
    v.map(f64::from)
}

fn det3(m: [[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Solve the leading `size x size` block of `gram * lambda = rhs` (Cramer's rule; `size` is 1, 2 or 3).
/// `None` when the block is degenerate.
fn solve_gram(gram: [[f64; 3]; 3], rhs: Vec3, size: usize) -> Option<Vec3> {
    match size {
        1 => (gram[0][0] > MIN_GRAM_DETERMINANT).then(|| [rhs[0] / gram[0][0], 0.0, 0.0]),
        2 => {
            let det = gram[0][0] * gram[1][1] - gram[0][1] * gram[1][0];
            (det > MIN_GRAM_DETERMINANT).then(|| {
                [
                    (rhs[0] * gram[1][1] - gram[0][1] * rhs[1]) / det,
                    (gram[0][0] * rhs[1] - rhs[0] * gram[1][0]) / det,
                    0.0,
                ]
            })
        }
        3 => {
            let det = det3(gram);
            if det.is_nan() || det <= MIN_GRAM_DETERMINANT {
                return None;
            }
            let mut lambda = [0.0; 3];
            for (column, value) in lambda.iter_mut().enumerate() {
                let mut replaced = gram;
                for (row, line) in replaced.iter_mut().enumerate() {
                    line[column] = rhs[row];
                }
                *value = det3(replaced) / det;
            }
            Some(lambda)
        }
        _ => None,
    }
}

/// The god-object proxy of one device against the planes of its local model.
///
/// Force: for a constraint plane `j`, `k_j lambda_j n_j`, where `p - x = sum_j lambda_j n_j` (`lambda_j >= 0`,
/// non-zero only for planes the proxy rests on) decomposes the proxy spring over the planes it rests on: on one
/// plane `lambda_j` is the device's depth below it, on the edge of two perpendicular planes each plane pushes
/// with its own depth, and with equal stiffness the sum is exactly Zilles and Salisbury's `k (p - x)`. For a
/// plane the proxy was behind, the penalty `k_j max(0, offset_j - n_j . x) n_j`. Each plane damps only the
/// approach, `b_j max(0, -n_j . v) n_j`, capped at [`MAX_DRAG_PER_NORMAL`] times that plane's spring force so
/// the force has no step at touch-down.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlaneProxy {
    position_mm: Vec3,
    has_proxy: bool,
}

impl PlaneProxy {
    /// No proxy yet: the next [`PlaneProxy::step`] starts it at the device.
    pub const fn new() -> Self {
        Self {
            position_mm: [0.0; 3],
            has_proxy: false,
        }
    }

    /// Forget the proxy (the next step starts it at the device).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The proxy position, mm (device frame), if there is one.
    pub fn position_mm(&self) -> Option<[f32; 3]> {
        self.has_proxy.then(|| self.position_mm.map(|c| c as f32))
    }

    /// Move the proxy for the device at `position_mm` and return the force of `planes` (at most
    /// [`MAX_CONTACT_PLANES`] are used) on the device moving at `velocity_mm_s`, N.
    ///
    /// The constraints are the planes the previous proxy was on or outside of (within
    /// [`CONSTRAINT_TOLERANCE_MM`]); without a previous proxy, the planes the device is on or outside of. The
    /// new proxy is the point nearest the device that satisfies them: every subset of up to three constraint
    /// planes gives a candidate (the device projected onto the plane, the line of two, the point of three;
    /// degenerate subsets skipped) and the nearest one clear of all constraints wins (the device itself when
    /// it is clear). That is the projection onto the constraint polyhedron, and its subset's multipliers are
    /// the `lambda_j` of the force.
    ///
    /// Real-time contract: no allocation, never blocks, never panics; non-finite input or planes give zero
    /// force and reset the proxy.
    pub fn step(
        &mut self,
        planes: &[ContactPlane],
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) -> [f32; 3] {
        const ZERO: [f32; 3] = [0.0; 3];
        if !(all_finite(position_mm) && all_finite(velocity_mm_s)) {
            self.reset();
            return ZERO;
        }
        let planes = &planes[..planes.len().min(MAX_CONTACT_PLANES)];
        let x = to_f64(position_mm);
        let previous = if self.has_proxy { self.position_mm } else { x };

        // Constraint planes, by index into `planes`.
        let mut constraints = [0usize; MAX_CONTACT_PLANES];
        let mut constraint_count = 0;
        let mut is_constraint = [false; MAX_CONTACT_PLANES];
        for (j, plane) in planes.iter().enumerate() {
            if dot(to_f64(plane.normal), previous)
                >= f64::from(plane.offset_mm) - CONSTRAINT_TOLERANCE_MM
            {
                constraints[constraint_count] = j;
                constraint_count += 1;
                is_constraint[j] = true;
            }
        }
        let is_clear = |p: Vec3| {
            constraints[..constraint_count].iter().all(|&j| {
                dot(to_f64(planes[j].normal), p)
                    >= f64::from(planes[j].offset_mm) - FEASIBLE_TOLERANCE_MM
            })
        };

        // The device itself, then every subset of one to three constraint planes.
        let mut best: Option<(f64, Vec3, [f64; MAX_CONTACT_PLANES])> =
            is_clear(x).then_some((0.0, x, [0.0; MAX_CONTACT_PLANES]));
        for mask in 1u32..(1 << constraint_count) {
            let size = mask.count_ones() as usize;
            if size > 3 {
                continue;
            }
            let mut members = [0usize; 3];
            let mut filled = 0;
            for (bit, &j) in constraints[..constraint_count].iter().enumerate() {
                if mask & (1 << bit) != 0 {
                    members[filled] = j;
                    filled += 1;
                }
            }
            let mut gram = [[0.0; 3]; 3];
            let mut rhs = [0.0; 3];
            for a in 0..size {
                let n_a = to_f64(planes[members[a]].normal);
                rhs[a] = f64::from(planes[members[a]].offset_mm) - dot(n_a, x);
                for b in 0..size {
                    gram[a][b] = dot(n_a, to_f64(planes[members[b]].normal));
                }
            }
            let Some(lambda) = solve_gram(gram, rhs, size) else {
                continue;
            };
            let mut candidate = x;
            let mut multipliers = [0.0; MAX_CONTACT_PLANES];
            for a in 0..size {
                let n_a = to_f64(planes[members[a]].normal);
                for (c, n) in candidate.iter_mut().zip(n_a) {
                    *c += lambda[a] * n;
                }
                multipliers[members[a]] = lambda[a];
            }
            let offset: Vec3 = std::array::from_fn(|i| candidate[i] - x[i]);
            let distance_sq = dot(offset, offset);
            let nearer = best.is_none_or(|(best_sq, _, _)| distance_sq < best_sq);
            if nearer && distance_sq.is_finite() && is_clear(candidate) {
                best = Some((distance_sq, candidate, multipliers));
            }
        }

        // The previous proxy satisfies every constraint, so some candidate should; if rounding or a skipped
        // degenerate subset left none, hold the proxy and let every plane push as a penalty.
        let (proxy, multipliers) = match best {
            Some((_, proxy, multipliers)) => (proxy, Some(multipliers)),
            None => (previous, None),
        };
        self.position_mm = proxy;
        self.has_proxy = true;

        let v = to_f64(velocity_mm_s);
        let mut force_n = [0.0f64; 3];
        for (j, plane) in planes.iter().enumerate() {
            let n = to_f64(plane.normal);
            let depth_mm = match multipliers {
                Some(lambda) if is_constraint[j] => lambda[j],
                _ => f64::from(plane.offset_mm) - dot(n, x),
            };
            if depth_mm.is_nan() || depth_mm <= 0.0 {
                continue;
            }
            let spring_n = f64::from(plane.stiffness_n_per_mm) * depth_mm;
            let approach_mm_s = (-dot(n, v)).max(0.0);
            let damping_n = (f64::from(plane.damping_n_s_per_mm) * approach_mm_s)
                .min(f64::from(MAX_DRAG_PER_NORMAL) * spring_n);
            for (f, n) in force_n.iter_mut().zip(n) {
                *f += (spring_n + damping_n) * n;
            }
        }
        let force_n = force_n.map(|c| c as f32);
        if all_finite(force_n) && proxy.iter().all(|c| c.is_finite()) {
            force_n
        } else {
            self.reset();
            ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(normal: [f32; 3], offset_mm: f32, k: f32, b: f32) -> ContactPlane {
        ContactPlane {
            normal,
            offset_mm,
            stiffness_n_per_mm: k,
            damping_n_s_per_mm: b,
        }
    }

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
    }

    const FLOOR: ContactPlane = ContactPlane {
        normal: [0.0, 0.0, 1.0],
        offset_mm: 0.0,
        stiffness_n_per_mm: 0.5,
        damping_n_s_per_mm: 0.0,
    };

    #[test]
    fn pushed_ten_mm_below_a_plane_gives_five_newtons() {
        let mut proxy = PlaneProxy::new();
        assert_eq!(proxy.step(&[FLOOR], [1.0, 2.0, 3.0], [0.0; 3]), [0.0; 3]);
        let mut f = [0.0; 3];
        for i in 1..=100 {
            f = proxy.step(&[FLOOR], [1.0, 2.0, 3.0 - 0.13 * i as f32], [0.0; 3]);
        }
        assert!(close(f, [0.0, 0.0, 5.0], 1e-5), "{f:?}");
        let p = proxy.position_mm().unwrap();
        assert!(close(p, [1.0, 2.0, 0.0], 1e-6), "{p:?}");
    }

    #[test]
    fn a_thirty_mm_jump_through_a_plane_is_still_pushed_back_out() {
        let mut proxy = PlaneProxy::new();
        assert_eq!(proxy.step(&[FLOOR], [0.0, 0.0, 5.0], [0.0; 3]), [0.0; 3]);
        // One tick from 5 mm above to 25 mm below.
        let f = proxy.step(&[FLOOR], [0.0, 0.0, -25.0], [0.0; 3]);
        assert!(close(f, [0.0, 0.0, 12.5], 1e-5), "{f:?}");
        assert!(close(proxy.position_mm().unwrap(), [0.0; 3], 1e-6));
        // The proxy slides along the surface, above the device, as the device moves underneath.
        let f = proxy.step(&[FLOOR], [7.0, -3.0, -20.0], [0.0; 3]);
        assert!(close(f, [0.0, 0.0, 10.0], 1e-5), "{f:?}");
        assert!(close(proxy.position_mm().unwrap(), [7.0, -3.0, 0.0], 1e-6));
    }

    #[test]
    fn a_device_that_starts_inside_is_pushed_by_a_penalty_not_launched() {
        let mut proxy = PlaneProxy::new();
        let f = proxy.step(&[FLOOR], [0.0, 0.0, -4.0], [0.0; 3]);
        assert!(close(f, [0.0, 0.0, 2.0], 1e-5), "{f:?}");
        // The proxy stays with the device (it is not projected out).
        assert_eq!(proxy.position_mm(), Some([0.0, 0.0, -4.0]));
        // Once out, the plane is a constraint again.
        assert_eq!(proxy.step(&[FLOOR], [0.0, 0.0, 0.5], [0.0; 3]), [0.0; 3]);
        proxy.step(&[FLOOR], [0.0, 0.0, -30.0], [0.0; 3]);
        assert!(close(proxy.position_mm().unwrap(), [0.0; 3], 1e-6));
        // reset() forgets the proxy: from inside, a penalty again.
        proxy.reset();
        assert_eq!(proxy.position_mm(), None);
        let f = proxy.step(&[FLOOR], [0.0, 0.0, -6.0], [0.0; 3]);
        assert!(close(f, [0.0, 0.0, 3.0], 1e-5), "{f:?}");
        assert_eq!(proxy.position_mm(), Some([0.0, 0.0, -6.0]));
    }

    #[test]
    fn a_perpendicular_wedge_puts_the_proxy_on_the_edge_and_sums_both_planes() {
        // Free space x >= 0 and z >= 0; the edge is the y axis.
        let wall = plane([1.0, 0.0, 0.0], 0.0, 0.5, 0.0);
        let floor = plane([0.0, 0.0, 1.0], 0.0, 0.3, 0.0);
        let mut proxy = PlaneProxy::new();
        proxy.step(&[wall, floor], [1.0, 4.0, 1.0], [0.0; 3]);
        let f = proxy.step(&[wall, floor], [-2.0, 4.0, -3.0], [0.0; 3]);
        assert!(close(proxy.position_mm().unwrap(), [0.0, 4.0, 0.0], 1e-6));
        assert!(close(f, [0.5 * 2.0, 0.0, 0.3 * 3.0], 1e-5), "{f:?}");
    }

    #[test]
    fn a_v_groove_puts_the_proxy_on_the_edge_and_springs_to_it() {
        // A 90 degree groove along y, its faces at 45 degrees: free space |x| <= z.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let left = plane([s, 0.0, s], 0.0, 0.4, 0.0);
        let right = plane([-s, 0.0, s], 0.0, 0.4, 0.0);
        let mut proxy = PlaneProxy::new();
        proxy.step(&[left, right], [0.0, 2.0, 5.0], [0.0; 3]);
        let x = [0.5, 2.0, -3.0];
        let f = proxy.step(&[left, right], x, [0.0; 3]);
        let p = proxy.position_mm().unwrap();
        assert!(close(p, [0.0, 2.0, 0.0], 1e-6), "{p:?}");
        // Equal stiffness: exactly the god-object spring k (p - x); here also sum_j k (n_j . (p - x)) n_j.
        let expected: [f32; 3] = std::array::from_fn(|i| 0.4 * (p[i] - x[i]));
        assert!(close(f, expected, 1e-5), "{f:?} vs {expected:?}");
    }

    #[test]
    fn no_force_above_the_planes() {
        let wall = plane([1.0, 0.0, 0.0], -5.0, 0.5, 0.1);
        let mut proxy = PlaneProxy::new();
        let mut rng = fastrand::Rng::with_seed(3);
        for _ in 0..1000 {
            let x = [
                rng.f32() * 50.0 - 4.9,
                rng.f32() * 50.0 - 25.0,
                rng.f32() * 50.0,
            ];
            let v = [
                rng.f32() * 400.0 - 200.0,
                rng.f32() * 400.0 - 200.0,
                rng.f32() * 400.0 - 200.0,
            ];
            assert_eq!(proxy.step(&[FLOOR, wall], x, v), [0.0; 3], "x {x:?}");
            assert_eq!(proxy.position_mm(), Some(x));
        }
    }

    #[test]
    fn damping_resists_only_the_approach() {
        let damped = plane([0.0, 0.0, 1.0], 0.0, 0.5, 0.01);
        let mut proxy = PlaneProxy::new();
        proxy.step(&[damped], [0.0, 0.0, 1.0], [0.0; 3]);
        // 2 mm deep: 1 N of spring.
        let moving_in = proxy.step(&[damped], [0.0, 0.0, -2.0], [0.0, 0.0, -20.0]);
        assert!(close(moving_in, [0.0, 0.0, 1.2], 1e-5), "{moving_in:?}");
        let moving_out = proxy.step(&[damped], [0.0, 0.0, -2.0], [0.0, 0.0, 20.0]);
        assert!(close(moving_out, [0.0, 0.0, 1.0], 1e-5), "{moving_out:?}");
        let sliding = proxy.step(&[damped], [0.0, 0.0, -2.0], [50.0, -30.0, 0.0]);
        assert!(close(sliding, [0.0, 0.0, 1.0], 1e-5), "{sliding:?}");
    }

    #[test]
    fn touch_down_at_speed_has_no_step() {
        // Uncapped, 0.01 N s/mm at 200 mm/s would step by 2 N at the surface.
        let damped = plane([0.0, 0.0, 1.0], 0.0, 0.5, 0.01);
        let mut proxy = PlaneProxy::new();
        let mut previous = proxy.step(&[damped], [0.0, 0.0, 1.0], [0.0, 0.0, -200.0]);
        let mut max_step_n = 0.0f32;
        for i in 1..=200 {
            let z_mm = 1.0 - 0.01 * i as f32;
            let f = proxy.step(&[damped], [0.0, 0.0, z_mm], [0.0, 0.0, -200.0]);
            max_step_n = max_step_n.max((f[2] - previous[2]).abs());
            previous = f;
        }
        // 1 mm deep: 0.5 N spring + damping capped at 0.5 N.
        assert!(close(previous, [0.0, 0.0, 1.0], 1e-5), "{previous:?}");
        // Spring and capped damping each change by 0.005 N per 0.01 mm step.
        assert!(max_step_n <= 0.0101, "max step {max_step_n} N");
    }

    #[test]
    fn non_finite_input_gives_zero_and_resets() {
        let mut proxy = PlaneProxy::new();
        proxy.step(&[FLOOR], [0.0, 0.0, 1.0], [0.0; 3]);
        assert_eq!(
            proxy.step(&[FLOOR], [0.0, f32::NAN, -1.0], [0.0; 3]),
            [0.0; 3]
        );
        assert_eq!(proxy.position_mm(), None);
        let bad_plane = plane([0.0, 0.0, 1.0], 0.0, f32::INFINITY, 0.0);
        proxy.step(&[bad_plane], [0.0, 0.0, 1.0], [0.0; 3]);
        assert_eq!(
            proxy.step(&[bad_plane], [0.0, 0.0, -1.0], [0.0; 3]),
            [0.0; 3]
        );
        assert_eq!(proxy.position_mm(), None);
    }
}
