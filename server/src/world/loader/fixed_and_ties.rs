//! Fixed nodes (boxes and planes) and ties between objects.

use toml::Spanned;

use crate::tissue::{TieSet, Vec3};
use crate::world::file_format::{FixedSection, TieSection};

use super::*;

impl Context<'_> {
    pub(super) fn fixed(
        &self,
        key: &str,
        selection: &Spanned<FixedSection>,
    ) -> Result<FixedSelection, WorldError> {
        let finite = |v: &[f32]| v.iter().all(|c| c.is_finite());
        match selection.get_ref() {
            FixedSection::Box { min_mm, max_mm } => {
                let ok = finite(min_mm) && finite(max_mm) && (0..3).all(|a| min_mm[a] <= max_mm[a]);
                self.check(
                    selection,
                    key,
                    ok,
                    "box needs finite min_mm <= max_mm on every axis",
                )?;
                Ok(FixedSelection::Box {
                    min_mm: *min_mm,
                    max_mm: *max_mm,
                })
            }
            FixedSection::Plane {
                point_mm,
                normal,
                tolerance_mm,
            } => {
                let len = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
                let ok = finite(point_mm)
                    && finite(normal)
                    && len > 1e-6
                    && tolerance_mm.is_finite()
                    && *tolerance_mm >= 0.0;
                self.check(
                    selection,
                    key,
                    ok,
                    "plane needs a finite point_mm, a non-zero normal and tolerance_mm >= 0",
                )?;
                Ok(FixedSelection::Plane {
                    point_mm: *point_mm,
                    normal: normal.map(|c| c / len),
                    tolerance_mm: *tolerance_mm,
                })
            }
        }
    }

    pub(super) fn tie(
        &self,
        i: usize,
        tie: &Spanned<TieSection>,
        objects: &[ObjectSpec],
    ) -> Result<TieSet, WorldError> {
        let key = format!("ties[{i}]");
        let t = tie.get_ref();
        let find = |name: &str| objects.iter().position(|o| o.name == name);
        let (Some(a), Some(b)) = (find(&t.objects[0]), find(&t.objects[1])) else {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "names an unknown object (known: {})",
                    listed(objects.iter().map(|o| o.name.as_str()))
                ),
            ));
        };
        self.check(
            tie,
            &format!("{key}.objects"),
            a != b,
            "ties link two different objects",
        )?;
        if let Some(o) = [a, b].into_iter().find(|&o| objects[o].ticks_per_step > 1) {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "`{}` steps at its own rate (`step_hz`): ties couple two objects every substep; drop one of them",
                    objects[o].name
                ),
            ));
        }
        if let Some(o) = [a, b].into_iter().find(|&o| objects[o].region.is_some()) {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "`{}` is region-tracked (`region`): a tied object moves where the tie pulls it, not only where a tool touches; drop one of them",
                    objects[o].name
                ),
            ));
        }
        self.check(
            tie,
            &format!("{key}.within_mm"),
            t.within_mm.is_finite() && t.within_mm > 0.0,
            "must be positive",
        )?;
        self.check(
            tie,
            &format!("{key}.stiffness_n_per_mm"),
            t.stiffness_n_per_mm.is_finite() && t.stiffness_n_per_mm > 0.0,
            "must be positive",
        )?;
        self.check(
            tie,
            &format!("{key}.damping_n_s_per_mm"),
            t.damping_n_s_per_mm.is_finite() && t.damping_n_s_per_mm >= 0.0,
            "must be >= 0",
        )?;
        let to_vec = |p: [f32; 3]| Vec3::new(p[0], p[1], p[2]);
        let nodes_b = &objects[b].mesh.positions_mm;
        let mut pairs = Vec::new();
        for (na, pa) in objects[a].mesh.positions_mm.iter().enumerate() {
            let pa = to_vec(*pa);
            let nearest = nodes_b
                .iter()
                .enumerate()
                .map(|(nb, pb)| (nb, (to_vec(*pb) - pa).norm()))
                .min_by(|x, y| x.1.total_cmp(&y.1));
            if let Some((nb, distance)) = nearest
                && distance <= t.within_mm
            {
                pairs.push((na as u32, nb as u32, to_vec(nodes_b[nb]) - pa));
            }
        }
        if pairs.is_empty() {
            return Err(self.invalid(
                tie,
                &format!("{key}.within_mm"),
                format!(
                    "no node of `{}` lies within {} mm of `{}`",
                    t.objects[0], t.within_mm, t.objects[1]
                ),
            ));
        }
        Ok(TieSet {
            object_a: a,
            object_b: b,
            pairs,
            stiffness_n_per_mm: t.stiffness_n_per_mm,
            damping_n_s_per_mm: t.damping_n_s_per_mm,
        })
    }
}
