//! The local model of the tissue around one tool: what a hapticserver renders every millisecond in
//! latency-moderated mode.
//!
//! Owns: [`LocalModel`], [`ContactPlane`], the symmetric 3x3 layout they use ([`Sym3`]) and the domain checks
//! (finite, positive semi-definite, radius and fade, plane normals). Must not: evaluate the model (that is the
//! hapticserver's `render` module) or build it (the server's `haptics` module).
//!
//! Sign convention (the one every producer and renderer follows): with the device at `x` (mm, device frame)
//! moving at `v` (mm/s), the linear part renders `f = f0 - K (x - x0) - D v` (N), where `K` (N/mm) and `D`
//! (N s/mm) are symmetric positive semi-definite: pushing into the tissue raises the force that pushes back,
//! and motion is resisted. The linear part is one-sided along the contact normal (the direction of `f0`): it
//! never pulls the tool into the tissue; unless the tool holds tissue ([`LocalModel::attached`]: a grasp's
//! points), when it pulls both ways. While a blade cuts, the model also carries the drag of cutting
//! ([`LocalModel::cut_drag_n`]), rendered against the device's current motion: `-F v / sqrt(|v|^2 + v_s^2)`;
//! with [`LocalModel::cut_facet_mm`], `F` is the sawtooth of the facets the edge cuts, which the device makes
//! from its own travel.
//! A frictional contact carries a friction cone ([`LocalModel::friction_coefficient`]) and a stick spring
//! that the device renders about a stick point of its own; its `f0` is then the push alone.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, check};
use crate::messages::puncture_term::PunctureTerm;

/// Planes a model can carry.
pub const MAX_CONTACT_PLANES: usize = 4;

/// A symmetric 3x3 matrix as its upper triangle: `[xx, yy, zz, xy, xz, yz]`.
pub type Sym3 = [f32; 6];

/// Expand a [`Sym3`] to rows.
pub fn sym3_rows(m: &Sym3) -> [[f32; 3]; 3] {
    [[m[0], m[3], m[4]], [m[3], m[1], m[5]], [m[4], m[5], m[2]]]
}

/// `m * v` for a [`Sym3`].
pub fn sym3_mul(m: &Sym3, v: &[f32; 3]) -> [f32; 3] {
    [
        m[0] * v[0] + m[3] * v[1] + m[4] * v[2],
        m[3] * v[0] + m[1] * v[1] + m[5] * v[2],
        m[4] * v[0] + m[5] * v[1] + m[2] * v[2],
    ]
}

/// Whether a symmetric matrix is positive semi-definite: every principal minor (the three diagonal entries,
/// the three 2x2 minors and the determinant) is non-negative, within a tolerance relative to its scale (an
/// f32 eigen-decomposition on the server can leave -1e-7 where zero was meant). Sylvester's criterion for
/// semi-definiteness needs all principal minors, not only the leading ones.
pub fn sym3_is_psd(m: &Sym3) -> bool {
    let scale = m.iter().fold(0.0f64, |s, v| s.max(f64::from(v.abs())));
    if scale == 0.0 {
        return true;
    }
    let [xx, yy, zz, xy, xz, yz] = m.map(|v| f64::from(v) / scale);
    const TOL: f64 = 1e-5;
    let minors1 = [xx, yy, zz];
    let minors2 = [xx * yy - xy * xy, xx * zz - xz * xz, yy * zz - yz * yz];
    let det = xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz);
    minors1.iter().all(|&v| v >= -TOL) && minors2.iter().all(|&v| v >= -TOL) && det >= -TOL
}

/// A unilateral contact plane: a surface near the tool that pushes the tool out and never pulls.
///
/// The tool origin is clear of the surface while `normal . x >= offset_mm`; below that the plane pushes along
/// `normal` with `stiffness * depth` and damps the approach speed. The offset already accounts for the tool's
/// own extent (a 4 mm sphere's plane sits 4 mm above the tissue surface). Units: mm, N/mm, N s/mm; device frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ContactPlane {
    /// Outward unit normal (out of the tissue), device frame.
    pub normal: [f32; 3],
    /// Plane offset along the normal, mm.
    pub offset_mm: f32,
    /// Stiffness against penetration, N/mm (>= 0).
    pub stiffness_n_per_mm: f32,
    /// Damping of the penetration speed, N s/mm (>= 0).
    pub damping_n_s_per_mm: f32,
}

/// The tissue around one tool, linearised at the tool's server-side position, for rendering at the device.
///
/// Travels inside [`crate::ForceMode::LocalModel`]; the enclosing [`crate::ForceCommand`] names the pose it
/// was built from (`echo_pose_seq`, `echo_device_time_ns`). Units: mm, N, N/mm, N s/mm, mJ; device frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct LocalModel {
    /// Server simulated time the model was built at, ns.
    pub server_time_ns: u64,
    /// The tool touches tissue: the linear part applies. False: only the planes do.
    pub in_contact: bool,
    /// Tool position the model is linearised about, mm.
    pub x0_mm: [f32; 3],
    /// Force the tissue exerts on the tool at `x0_mm`, N.
    pub f0_n: [f32; 3],
    /// Contact stiffness `K`, N/mm, symmetric positive semi-definite ([`Sym3`] layout).
    pub stiffness_n_per_mm: Sym3,
    /// Contact damping `D`, N s/mm, symmetric positive semi-definite.
    pub damping_n_s_per_mm: Sym3,
    /// The linear part holds within this distance of `x0_mm`, mm (> 0).
    pub radius_mm: f32,
    /// Over the last `fade_mm` inside the radius the linear part fades smoothly to zero (0 < fade <= radius).
    pub fade_mm: f32,
    /// Unilateral planes (the first `plane_count` are used).
    pub planes: [ContactPlane; MAX_CONTACT_PLANES],
    /// Planes in use (<= [`MAX_CONTACT_PLANES`]).
    pub plane_count: u8,
    /// Energy this port may output beyond what its own hand put in, mJ (>= 0): work the other ports did on the
    /// shared tissue, granted by the server's energy budget to the device's passivity controller.
    pub energy_allowance_mj: f32,
    /// The tool holds tissue (a grasp's attachments): the linear part is bilateral, `f0 - K (x - x0) - D v`
    /// whichever way the device moves (within the radius), and `K` is the full 3x3 stiffness of the held
    /// tissue. False: one-sided along the contact normal.
    pub attached: bool,
    /// The drag of cutting while a blade cuts, N (>= 0; 0: not cutting): a force of this size against the
    /// device's current motion, smoothed below [`CUT_DRAG_SMOOTHING_MM_S`]. Not part of `f0`.
    pub cut_drag_n: f32,
    /// Coulomb's coefficient of the friction the device renders from its own stick point (0..=2; 0: no
    /// friction term). With friction, `f0` is the contact's push alone: the tangential force is
    /// `-k_t P (x - a)` about a stick point `a` the device keeps, `P` the projection onto the surface
    /// (normal to `f0`), capped at this coefficient times the rendered normal force; past the cap `a` slides.
    pub friction_coefficient: f32,
    /// The stick spring `k_t`, N/mm (>= 0; 0: no friction term).
    pub stick_stiffness_n_per_mm: f32,
    /// How far the blade's edge travels between the facets it cuts, mm (>= 0; 0: the drag is `cut_drag_n`
    /// throughout). Positive: `cut_drag_n` is the drag as a facet is cut, and the device renders the
    /// sawtooth the tissue makes, `cut_drag_n * exp(-t / CUT_DRAG_TAU_S)` with `t` the time since it last
    /// travelled another `cut_facet_mm`, against its own motion.
    pub cut_facet_mm: f32,
    /// A needle's tip pressing a surface ([`PunctureTerm`]; inactive otherwise): the device pops it locally
    /// when its own rendered push along the tip passes the threshold.
    pub puncture: PunctureTerm,
}

/// The time constant of the drag of cutting's decay after a facet is cut, s: at a steady 10-20 mm/s an edge
/// crosses a 1 mm mesh's facets every 50-100 ms, and the drag holds in between.
pub const CUT_DRAG_TAU_S: f32 = 0.1;

/// The largest friction coefficient a model may carry (as the world file's `friction_coefficient`).
pub const MAX_FRICTION_COEFFICIENT: f32 = 2.0;

/// Below this speed the drag of cutting fades with the speed (`-F v / sqrt(|v|^2 + v_s^2)`), mm/s: the drag
/// is continuous through a stop, and a hand at rest feels none.
pub const CUT_DRAG_SMOOTHING_MM_S: f32 = 2.0;

impl LocalModel {
    /// The planes in use.
    pub fn active_planes(&self) -> &[ContactPlane] {
        &self.planes[..usize::from(self.plane_count).min(MAX_CONTACT_PLANES)]
    }

    /// Domain checks: every number finite, `K` and `D` positive semi-definite, `0 < fade <= radius`, at most
    /// [`MAX_CONTACT_PLANES`] planes with unit normals and non-negative stiffness and damping, a non-negative
    /// allowance.
    pub fn validate(&self) -> Result<(), FieldError> {
        check::finite("local_model.x0_mm", &self.x0_mm)?;
        check::finite("local_model.f0_n", &self.f0_n)?;
        check::finite("local_model.stiffness_n_per_mm", &self.stiffness_n_per_mm)?;
        check::finite("local_model.damping_n_s_per_mm", &self.damping_n_s_per_mm)?;
        check::finite(
            "local_model.radius_mm",
            &[
                self.radius_mm,
                self.fade_mm,
                self.energy_allowance_mj,
                self.cut_drag_n,
            ],
        )?;
        if self.cut_drag_n < 0.0 {
            return Err(("local_model.cut_drag_n", "negative"));
        }
        check::finite("local_model.cut_facet_mm", &[self.cut_facet_mm])?;
        if self.cut_facet_mm < 0.0 {
            return Err(("local_model.cut_facet_mm", "negative"));
        }
        check::finite(
            "local_model.friction_coefficient",
            &[self.friction_coefficient, self.stick_stiffness_n_per_mm],
        )?;
        if !(0.0..=MAX_FRICTION_COEFFICIENT).contains(&self.friction_coefficient) {
            return Err(("local_model.friction_coefficient", "must be 0 to 2"));
        }
        if self.stick_stiffness_n_per_mm < 0.0 {
            return Err(("local_model.stick_stiffness_n_per_mm", "negative"));
        }
        if !sym3_is_psd(&self.stiffness_n_per_mm) {
            return Err((
                "local_model.stiffness_n_per_mm",
                "not positive semi-definite",
            ));
        }
        if !sym3_is_psd(&self.damping_n_s_per_mm) {
            return Err((
                "local_model.damping_n_s_per_mm",
                "not positive semi-definite",
            ));
        }
        if self.radius_mm <= 0.0 {
            return Err(("local_model.radius_mm", "must be > 0"));
        }
        if !(self.fade_mm > 0.0 && self.fade_mm <= self.radius_mm) {
            return Err(("local_model.fade_mm", "must be > 0 and <= radius_mm"));
        }
        if usize::from(self.plane_count) > MAX_CONTACT_PLANES {
            return Err(("local_model.plane_count", "more than 4 planes"));
        }
        if self.energy_allowance_mj < 0.0 {
            return Err(("local_model.energy_allowance_mj", "negative"));
        }
        self.puncture.validate()?;
        for plane in self.active_planes() {
            check::finite("local_model.planes.normal", &plane.normal)?;
            check::finite(
                "local_model.planes.offset_mm",
                &[
                    plane.offset_mm,
                    plane.stiffness_n_per_mm,
                    plane.damping_n_s_per_mm,
                ],
            )?;
            let norm = plane.normal.iter().map(|c| c * c).sum::<f32>().sqrt();
            if (norm - 1.0).abs() > 1e-3 {
                return Err(("local_model.planes.normal", "not unit length"));
            }
            if plane.stiffness_n_per_mm < 0.0 || plane.damping_n_s_per_mm < 0.0 {
                return Err(("local_model.planes.stiffness_n_per_mm", "negative"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psd_check_accepts_psd_and_refuses_indefinite() {
        assert!(sym3_is_psd(&[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
        assert!(sym3_is_psd(&[0.0; 6]));
        // Rank one, n n^T with n = (0.6, 0, 0.8): semi-definite.
        assert!(sym3_is_psd(&[0.36, 0.0, 0.64, 0.0, 0.48, 0.0]));
        // Negative diagonal.
        assert!(!sym3_is_psd(&[1.0, -0.1, 1.0, 0.0, 0.0, 0.0]));
        // Positive diagonal, indefinite 2x2 block (eigenvalues 3 and -1).
        assert!(!sym3_is_psd(&[1.0, 1.0, 0.0, 2.0, 0.0, 0.0]));
        // Leading minors fine (1, 1), but the (y, z) block has a zero diagonal and an off-diagonal term.
        assert!(!sym3_is_psd(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.5]));
    }

    #[test]
    fn sym3_mul_matches_rows() {
        let m = [1.0, 2.0, 3.0, 0.5, -0.25, 0.75];
        let v = [1.0, -2.0, 0.5];
        let rows = sym3_rows(&m);
        let expected: [f32; 3] =
            std::array::from_fn(|r| rows[r][0] * v[0] + rows[r][1] * v[1] + rows[r][2] * v[2]);
        assert_eq!(sym3_mul(&m, &v), expected);
    }
}
