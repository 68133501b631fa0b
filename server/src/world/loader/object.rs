//! An object's section: its mesh (OBJ surface, Gmsh volume, extrusion), integrator and step, multi-rate
//! rate, region of deformation.

use std::path::Path;

use crate::tissue::IntegratorName;
use crate::tissue::SurfaceMesh;
use crate::tissue::{RegionParams, Vec3};
use crate::world::extrude::{MAX_EXTRUDE_LAYERS, extrude_surface};
use crate::world::file_format::{ElasticModel, ObjectSection};
use crate::world::mesh_file::{load_obj_mesh, validate_closed};
use crate::world::tet_mesh::load_msh_mesh;

use super::*;

impl Context<'_> {
    pub(super) fn object(
        &self,
        i: usize,
        object: &ObjectSection,
        base: &Path,
        tick_dt_s: f32,
        gravity_mm_per_s2: [f32; 3],
    ) -> Result<ObjectSpec, WorldError> {
        let key = |k: &str| format!("objects[{i}].{k}");
        let name = object.name.get_ref().clone();
        if let Err(e) = sinew_protocol::keys::validate_segment("object", &name) {
            return Err(self.invalid(&object.name, &key("name"), e.to_string()));
        }
        let ticks_per_step = self.ticks_per_step(i, object, tick_dt_s)?;
        let step_dt_s = tick_dt_s * ticks_per_step as f32;
        let dt_s = self.positive(&object.dt_s, &key("dt_s"))?;
        let period = if ticks_per_step > 1 {
            "the object's step period (1 / step_hz)"
        } else {
            "the tick period"
        };
        self.check(
            &object.dt_s,
            &key("dt_s"),
            dt_s <= step_dt_s * (1.0 + 1e-6) && dt_s >= step_dt_s / MAX_SUBSTEPS,
            &format!(
                "must be within {period} {step_dt_s} s and at least 1/{MAX_SUBSTEPS} of it \
                 (at most {MAX_SUBSTEPS} substeps a step)"
            ),
        )?;
        let quant_margin_mm = self.positive(&object.quant_margin_mm, &key("quant_margin_mm"))?;
        let delta_tolerance_mm = *object.delta_tolerance_mm.get_ref();
        self.check(
            &object.delta_tolerance_mm,
            &key("delta_tolerance_mm"),
            delta_tolerance_mm.is_finite() && (0.0..=1.0).contains(&delta_tolerance_mm),
            &format!("must be in [0, 1] mm (got {delta_tolerance_mm})"),
        )?;
        let is_volume = object.extrude.is_some() || is_msh_path(object.mesh.get_ref());
        let model = object
            .model
            .as_ref()
            .map_or(ElasticModel::MassSpring, |m| *m.get_ref());
        if let Some(at) = &object.model
            && model == ElasticModel::FemCorotational
        {
            if !is_volume {
                return Err(self.invalid(
                    at,
                    &key("model"),
                    "fem-corotational needs tetrahedra: load a .msh mesh or add `extrude` to this OBJ",
                ));
            }
            if *object.integrator.get_ref() == IntegratorName::Xpbd {
                return Err(self.invalid(
                    &object.integrator,
                    &key("integrator"),
                    "xpbd constrains springs and volumes; fem-corotational needs a force-based integrator (implicit-euler is the one for tissue stiffness)",
                ));
            }
        }
        let material_keys = self.resolved_material(i, &object.material, is_volume)?;
        let material = self.material(i, &material_keys, is_volume, model, &object.name)?;
        let mut fixed = Vec::with_capacity(object.fixed.len());
        for (f, selection) in object.fixed.iter().enumerate() {
            fixed.push(self.fixed(&key(&format!("fixed[{f}]")), selection)?);
        }
        let (mut mesh, tets) = self.object_mesh(i, object, base)?;
        if let Some(at) = &object.offset_mm {
            let offset = *at.get_ref();
            self.check(
                at,
                &key("offset_mm"),
                offset.iter().all(|c| c.is_finite() && c.abs() <= 1e6),
                "must be finite and within a kilometre",
            )?;
            for p in &mut mesh.positions_mm {
                for k in 0..3 {
                    p[k] += offset[k];
                }
            }
        }
        if let Some(at) = &material_keys.tet_bulk_modulus_kpa
            && material.tet_bulk_modulus_n_per_mm2 > 0.0
            && tets.is_empty()
        {
            return Err(self.invalid(
                at,
                &key("material.tet_bulk_modulus_kpa"),
                "per-tetrahedron volume needs tetrahedra: load a .msh mesh or add `extrude` to this OBJ",
            ));
        }
        let integrator = *object.integrator.get_ref();
        let solver_iterations = match &object.solver_iterations {
            None => None,
            Some(at) => {
                let n = *at.get_ref();
                self.check(
                    at,
                    &key("solver_iterations"),
                    (1..=1000).contains(&n),
                    "must be in 1..=1000",
                )?;
                if matches!(
                    integrator,
                    IntegratorName::ExplicitEuler
                        | IntegratorName::SymplecticEuler
                        | IntegratorName::Rk2
                        | IntegratorName::Rk4
                ) {
                    return Err(self.invalid(
                        at,
                        &key("solver_iterations"),
                        format!("{} takes no iterations (only quasi-static, implicit-euler and xpbd do)", integrator.as_str()),
                    ));
                }
                Some(n)
            }
        };
        if material.global_bulk_modulus_n_per_mm2 > 0.0
            && let Err(reason) = validate_closed(&mesh)
        {
            return Err(WorldError::Mesh {
                file: self.path.to_owned(),
                line: self.line(object.mesh.span()),
                key: key("material.bulk_modulus_kpa"),
                mesh: object.mesh.get_ref().clone(),
                reason,
            });
        }
        let region = self.region(i, object, &material, gravity_mm_per_s2)?;
        self.multirate_combinations(i, object, &material, ticks_per_step)?;
        let spec = ObjectSpec {
            name,
            mesh,
            tets,
            integrator,
            solver_iterations,
            dt_s,
            quant_margin_mm,
            delta_tolerance_mm,
            material,
            fixed,
            region,
            triangle_contact: object.tool_contact.as_ref().is_some_and(|c| {
                *c.get_ref() == super::super::file_format::ToolContactName::NodesAndTriangles
            }),
            ticks_per_step,
        };
        // An explicit integrator must be stable at this dt for this stiffness, damping and mass.
        let model = crate::tissue::MassSpringModel::build(&spec, Vec3::from(gravity_mm_per_s2));
        if let Some(stable_dt_s) = crate::tissue::stability::max_stable_dt_s(integrator, &model)
            && dt_s > stable_dt_s
        {
            let undamped = material.drag_per_s == 0.0
                && material.damping_n_s_per_mm == 0.0
                && matches!(
                    integrator,
                    IntegratorName::ExplicitEuler | IntegratorName::Rk2
                );
            let hint = if undamped {
                "it is unstable at every step without damping: add damping or drag, or choose symplectic-euler".to_owned()
            } else {
                format!(
                    "its stability bound is {stable_dt_s:.6} s: lower dt_s, raise mass, or choose an implicit method"
                )
            };
            return Err(self.invalid(
                &object.dt_s,
                &key("dt_s"),
                format!(
                    "{dt_s} s is too large for {} with this stiffness, damping and mass: {hint}",
                    integrator.as_str()
                ),
            ));
        }
        if model.free_node_count() == 0 {
            return Err(self.invalid(
                &object.name,
                &key("fixed"),
                "every node is fixed: nothing can deform",
            ));
        }
        Ok(spec)
    }

    /// The object's mesh and tetrahedra: an OBJ surface (no tetrahedra), an OBJ surface extruded into a
    /// volume (`extrude`), or a Gmsh `.msh` volume.
    pub(super) fn object_mesh(
        &self,
        i: usize,
        object: &ObjectSection,
        base: &Path,
    ) -> Result<(SurfaceMesh, Vec<[u32; 4]>), WorldError> {
        let key = |k: &str| format!("objects[{i}].{k}");
        let mesh_error = |key: String, line: usize| {
            move |reason| WorldError::Mesh {
                file: self.path.to_owned(),
                line,
                key,
                mesh: object.mesh.get_ref().clone(),
                reason,
            }
        };
        let mesh_line = self.line(object.mesh.span());
        let path = base.join(object.mesh.get_ref());
        let scale_to_mm = object.units.to_mm();
        if is_msh_path(object.mesh.get_ref()) {
            if let Some(extrude) = &object.extrude {
                return Err(self.invalid(
                    extrude,
                    &key("extrude"),
                    "a .msh mesh is already a volume: remove `extrude` (it extrudes OBJ surfaces)",
                ));
            }
            let volume =
                load_msh_mesh(&path, scale_to_mm).map_err(mesh_error(key("mesh"), mesh_line))?;
            return Ok((volume.surface, volume.tets));
        }
        let surface =
            load_obj_mesh(&path, scale_to_mm).map_err(mesh_error(key("mesh"), mesh_line))?;
        let Some(extrude) = &object.extrude else {
            return Ok((surface, Vec::new()));
        };
        let section = extrude.get_ref();
        let thickness_mm = self.positive(&section.thickness_mm, &key("extrude.thickness_mm"))?;
        let layers = *section.layers.get_ref();
        self.check(
            &section.layers,
            &key("extrude.layers"),
            (1..=i64::from(MAX_EXTRUDE_LAYERS)).contains(&layers),
            &format!("must be in 1..={MAX_EXTRUDE_LAYERS} (got {layers})"),
        )?;
        let volume = extrude_surface(&surface, thickness_mm, layers as u32)
            .map_err(mesh_error(key("extrude"), self.line(extrude.span())))?;
        Ok((volume.surface, volume.tets))
    }

    /// Object `i`'s ticks per step from its optional `step_hz`: the tick rate must be a whole multiple of it,
    /// at most [`MAX_TICKS_PER_STEP`] times it.
    pub(super) fn ticks_per_step(
        &self,
        i: usize,
        object: &ObjectSection,
        tick_dt_s: f32,
    ) -> Result<u32, WorldError> {
        let Some(at) = &object.step_hz else {
            return Ok(1);
        };
        let key = format!("objects[{i}].step_hz");
        let step_hz = *at.get_ref();
        let tick_hz = 1.0 / f64::from(tick_dt_s);
        self.check(
            at,
            &key,
            // The tick rate comes back from the f32 tick period: a rate equal to it is within rounding.
            step_hz.is_finite() && step_hz > 0.0 && step_hz <= tick_hz * (1.0 + 1e-6),
            &format!("must be a positive rate no higher than sim.tick_hz = {tick_hz:.0} Hz (got {step_hz})"),
        )?;
        let ratio = tick_hz / step_hz;
        let ticks = ratio.round();
        self.check(
            at,
            &key,
            (ratio - ticks).abs() <= 1e-6 * ratio && ticks <= f64::from(MAX_TICKS_PER_STEP),
            &format!(
                "must divide sim.tick_hz = {tick_hz:.0} Hz a whole number of times, at most {MAX_TICKS_PER_STEP} \
                 (got {step_hz} Hz: {ratio:.3} ticks a step)"
            ),
        )?;
        Ok(ticks as u32)
    }

    /// What a multi-rate object (`step_hz` below the tick rate) cannot do yet: a region of deformation (it
    /// follows the tools tick by tick), tearing and burn shrink (they change the model the object's own thread
    /// steps).
    pub(super) fn multirate_combinations(
        &self,
        i: usize,
        object: &ObjectSection,
        material: &MaterialSpec,
        ticks_per_step: u32,
    ) -> Result<(), WorldError> {
        let Some(at) = object.step_hz.as_ref().filter(|_| ticks_per_step > 1) else {
            return Ok(());
        };
        let key = format!("objects[{i}].step_hz");
        self.check(
            at,
            &key,
            object.region.is_none(),
            "cannot be combined with `region`: a region follows the tools every tick; drop one of them",
        )?;
        self.check(
            at,
            &key,
            material.burn_shrink == 0.0,
            "cannot be combined with material.burn_shrink: a burn would change the model a multi-rate object's \
             own thread steps every tick the tip touches it",
        )?;
        Ok(())
    }

    /// The optional `region` table of object `i`, and the combinations region tracking cannot simulate.
    pub(super) fn region(
        &self,
        i: usize,
        object: &ObjectSection,
        material: &MaterialSpec,
        gravity_mm_per_s2: [f32; 3],
    ) -> Result<Option<RegionParams>, WorldError> {
        let Some(at) = &object.region else {
            return Ok(None);
        };
        let key = format!("objects[{i}].region");
        let threshold = &at.get_ref().threshold_mm;
        let threshold_mm = *threshold.get_ref();
        self.check(
            threshold,
            &format!("{key}.threshold_mm"),
            threshold_mm.is_finite() && threshold_mm > 0.0 && threshold_mm <= 1.0,
            &format!("must be in (0, 1] mm (got {threshold_mm})"),
        )?;
        self.check(
            at,
            &key,
            material.global_bulk_modulus_n_per_mm2 == 0.0,
            "cannot be combined with material.bulk_modulus_kpa: the global volume term couples every surface node",
        )?;
        self.check(
            at,
            &key,
            gravity_mm_per_s2 == [0.0; 3],
            "needs sim.gravity_mm_per_s2 = [0, 0, 0]: gravity moves the whole object, not a region",
        )?;
        Ok(Some(RegionParams { threshold_mm }))
    }
}
