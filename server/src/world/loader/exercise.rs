//! The world's exercise: targets, samples and their validation.

use toml::Spanned;

use crate::scene::{ExerciseKind, ExerciseSpec, PatternSpec, SampleSpec, TargetSpec};
use crate::world::file_format::{ExerciseSection, PatternSection, TargetSection};

use super::*;

impl Context<'_> {
    pub(super) fn exercise(
        &self,
        section: &Spanned<ExerciseSection>,
        tools: &[ToolSpec],
        objects: &[ObjectSpec],
    ) -> Result<ExerciseSpec, WorldError> {
        let e = section.get_ref();
        let name = e.name.get_ref().clone();
        self.check(&e.name, "exercise.name", !name.trim().is_empty(), "empty")?;
        let limit = *e.time_limit_s.get_ref();
        self.check(
            &e.time_limit_s,
            "exercise.time_limit_s",
            limit.is_finite() && limit > 0.0 && limit <= 86_400.0,
            &format!("must be a time in (0, 86400] s (got {limit})"),
        )?;
        let depth_limit_mm = match &e.depth_limit_mm {
            Some(at) => Some(self.positive(at, "exercise.depth_limit_mm")?),
            None => None,
        };
        if e.kind == ExerciseKind::AccurateTouch && depth_limit_mm.is_none() {
            return Err(self.invalid(
                section,
                "exercise.depth_limit_mm",
                "an accurate-touch exercise needs a depth limit",
            ));
        }
        if let (ExerciseKind::Suture, Some(at)) = (e.kind, &e.depth_limit_mm) {
            return Err(self.invalid(
                at,
                "exercise.depth_limit_mm",
                "a suture exercise judges punctures, not presses: it has no depth limit",
            ));
        }
        if let (ExerciseKind::PatternCutting, Some(at)) = (e.kind, &e.depth_limit_mm) {
            return Err(self.invalid(
                at,
                "exercise.depth_limit_mm",
                "a pattern-cutting exercise judges the cut, not presses: it has no depth limit",
            ));
        }
        let samples = self.exercise_samples(section, objects)?;
        let pattern = match &e.pattern {
            Some(at) => Some(self.exercise_pattern(at, e.kind, objects)?),
            None if e.kind == ExerciseKind::PatternCutting => {
                return Err(self.invalid(
                    section,
                    "exercise.pattern",
                    "missing: a pattern-cutting exercise marks its circles in an [exercise.pattern] table",
                ));
            }
            None => None,
        };
        let ranking = e.kind == ExerciseKind::StiffnessRanking;
        let untargeted = ranking || e.kind == ExerciseKind::PatternCutting;
        let list: &[Spanned<TargetSection>] = match &e.targets {
            Some(at) if untargeted => {
                return Err(self.invalid(
                    at,
                    "exercise.targets",
                    if ranking {
                        "a stiffness-ranking exercise has samples, not targets"
                    } else {
                        "a pattern-cutting exercise has a pattern, not targets"
                    },
                ));
            }
            Some(at) => {
                let list = at.get_ref();
                self.check(
                    at,
                    "exercise.targets",
                    e.kind != ExerciseKind::Suture || list.len() == 2,
                    &format!(
                        "a suture exercise has two targets, the entry mark then the exit mark (got {})",
                        list.len()
                    ),
                )?;
                self.check(
                    at,
                    "exercise.targets",
                    !list.is_empty() && list.len() <= MAX_EXERCISE_TARGETS,
                    &format!(
                        "needs 1 to {MAX_EXERCISE_TARGETS} targets (got {})",
                        list.len()
                    ),
                )?;
                list
            }
            None if untargeted => &[],
            None => {
                return Err(self.invalid(
                    section,
                    "exercise.targets",
                    "missing: list the targets as [[exercise.targets]] tables",
                ));
            }
        };
        let mut targets = Vec::with_capacity(list.len());
        for (i, target) in list.iter().enumerate() {
            let key = |k: &str| format!("exercise.targets[{i}].{k}");
            let t = target.get_ref();
            self.check(
                target,
                &key("at_mm"),
                t.at_mm.iter().all(|c| c.is_finite()),
                "must be finite",
            )?;
            self.check(
                target,
                &key("radius_mm"),
                t.radius_mm.is_finite() && t.radius_mm > 0.0,
                &format!("must be a positive number (got {})", t.radius_mm),
            )?;
            let tool = match &t.tool {
                Some(name) => {
                    Some(tools.iter().position(|s| &s.name == name).ok_or_else(|| {
                        self.invalid(
                            target,
                            &key("tool"),
                            format!(
                                "no tool named `{name}` (tools: {})",
                                listed(tools.iter().map(|s| s.name.as_str()))
                            ),
                        )
                    })?)
                }
                None if e.kind == ExerciseKind::Coordination => {
                    return Err(self.invalid(
                        target,
                        &key("tool"),
                        "a coordination target names the tool that must touch it",
                    ));
                }
                None => None,
            };
            targets.push(TargetSpec {
                at_mm: t.at_mm,
                radius_mm: t.radius_mm,
                tool,
            });
        }
        let wound = match &e.wound {
            Some(at) => Some(self.exercise_wound(at, e.kind, objects)?),
            None => None,
        };
        let knot = match &e.knot {
            Some(at) => {
                self.check(
                    at,
                    "exercise.knot",
                    e.kind == ExerciseKind::Suture || !*at.get_ref(),
                    "only a suture exercise is tied off with a knot",
                )?;
                *at.get_ref()
            }
            None => false,
        };
        Ok(ExerciseSpec {
            name,
            kind: e.kind,
            time_limit_s: limit,
            depth_limit_mm,
            targets,
            samples,
            wound,
            knot,
            pattern,
        })
    }

    /// A pattern-cutting exercise's circles: on a sheet of the world that is clipped somewhere outside them,
    /// the inner radius less than the outer, the centre on the sheet.
    fn exercise_pattern(
        &self,
        at: &Spanned<PatternSection>,
        kind: ExerciseKind,
        objects: &[ObjectSpec],
    ) -> Result<PatternSpec, WorldError> {
        self.check(
            at,
            "exercise.pattern",
            kind == ExerciseKind::PatternCutting,
            "only a pattern-cutting exercise marks a pattern",
        )?;
        let p = at.get_ref();
        let Some(object) = objects.iter().position(|o| o.name == p.object) else {
            return Err(self.invalid(
                at,
                "exercise.pattern.object",
                format!(
                    "no object named `{}` (objects: {})",
                    p.object,
                    listed(objects.iter().map(|o| o.name.as_str()))
                ),
            ));
        };
        let spec = &objects[object];
        self.check(
            at,
            "exercise.pattern.object",
            spec.tets.is_empty(),
            &format!(
                "`{}` is a volume: a pattern is cut out of a sheet",
                p.object
            ),
        )?;
        self.check(
            at,
            "exercise.pattern.centre_mm",
            p.centre_mm.iter().all(|c| c.is_finite()),
            "must be finite",
        )?;
        let (inner, outer) = (p.inner_radius_mm, p.outer_radius_mm);
        self.check(
            at,
            "exercise.pattern.inner_radius_mm",
            inner.is_finite() && inner > 0.0,
            &format!("must be a positive number (got {inner})"),
        )?;
        self.check(
            at,
            "exercise.pattern.outer_radius_mm",
            outer.is_finite() && outer > inner,
            &format!("must be more than the inner radius, {inner} mm (got {outer})"),
        )?;
        let centre = nalgebra::Vector3::from(p.centre_mm);
        let distance = |q: &[f32; 3]| (nalgebra::Vector3::from(*q) - centre).norm();
        let nearest = spec
            .mesh
            .positions_mm
            .iter()
            .map(distance)
            .fold(f32::INFINITY, f32::min);
        self.check(
            at,
            "exercise.pattern.centre_mm",
            nearest < inner,
            &format!(
                "lies {nearest} mm from the nearest vertex of `{}`: the centre must lie on the sheet, within the inner circle",
                p.object
            ),
        )?;
        let clipped = |q: &[f32; 3]| spec.fixed.iter().any(|f| f.contains(*q));
        self.check(
            at,
            "exercise.pattern.object",
            spec.mesh.positions_mm.iter().any(clipped),
            &format!(
                "`{}` has no fixed vertex: the sheet is held by clips ([[objects.fixed]]) and the pattern is cut free of them",
                p.object
            ),
        )?;
        self.check(
            at,
            "exercise.pattern.outer_radius_mm",
            !spec
                .mesh
                .positions_mm
                .iter()
                .any(|q| clipped(q) && distance(q) <= outer),
            &format!(
                "a fixed vertex of `{}` lies within the outer circle: the pattern could never come free",
                p.object
            ),
        )?;
        Ok(PatternSpec {
            object,
            centre_mm: p.centre_mm,
            inner_radius_mm: inner,
            outer_radius_mm: outer,
        })
    }

    /// A suture exercise's wound: two distinct objects of the world, by name.
    fn exercise_wound(
        &self,
        at: &Spanned<[String; 2]>,
        kind: ExerciseKind,
        objects: &[ObjectSpec],
    ) -> Result<[usize; 2], WorldError> {
        self.check(
            at,
            "exercise.wound",
            kind == ExerciseKind::Suture,
            "only a suture exercise names a wound",
        )?;
        let index = |name: &String| {
            objects.iter().position(|o| &o.name == name).ok_or_else(|| {
                self.invalid(
                    at,
                    "exercise.wound",
                    format!(
                        "no object named `{name}` (objects: {})",
                        listed(objects.iter().map(|o| o.name.as_str()))
                    ),
                )
            })
        };
        let [a, b] = at.get_ref();
        let (a, b) = (index(a)?, index(b)?);
        self.check(
            at,
            "exercise.wound",
            a != b,
            "names one object twice: a wound lies between two edges",
        )?;
        Ok([a, b])
    }

    /// A ranking exercise's samples: at least two distinct objects of the world (none for other kinds).
    pub(super) fn exercise_samples(
        &self,
        section: &Spanned<ExerciseSection>,
        objects: &[ObjectSpec],
    ) -> Result<Vec<SampleSpec>, WorldError> {
        let e = section.get_ref();
        let ranking = e.kind == ExerciseKind::StiffnessRanking;
        let Some(at) = &e.samples else {
            if ranking {
                return Err(self.invalid(
                    section,
                    "exercise.samples",
                    "missing: name the objects to rank, e.g. samples = [\"a\", \"b\"]",
                ));
            }
            return Ok(Vec::new());
        };
        self.check(
            at,
            "exercise.samples",
            ranking,
            "only a stiffness-ranking exercise has samples",
        )?;
        let names = at.get_ref();
        self.check(
            at,
            "exercise.samples",
            names.len() >= 2 && names.len() <= MAX_EXERCISE_TARGETS,
            &format!(
                "needs 2 to {MAX_EXERCISE_TARGETS} samples (got {})",
                names.len()
            ),
        )?;
        let mut samples: Vec<SampleSpec> = Vec::with_capacity(names.len());
        for name in names {
            let Some(object) = objects.iter().position(|o| &o.name == name) else {
                return Err(self.invalid(
                    at,
                    "exercise.samples",
                    format!(
                        "no object named `{name}` (objects: {})",
                        objects
                            .iter()
                            .map(|o| o.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            };
            if samples.iter().any(|s| s.object == object) {
                return Err(self.invalid(
                    at,
                    "exercise.samples",
                    format!("`{name}` is named twice"),
                ));
            }
            let spec = &objects[object];
            let mut min = [f32::MAX; 2];
            let mut max = [f32::MIN; 2];
            for p in &spec.mesh.positions_mm {
                for k in 0..2 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
            samples.push(SampleSpec {
                object,
                name: name.clone(),
                stiffness_n_per_mm: spec.material.stiffness_n_per_mm,
                min_xy_mm: min,
                max_xy_mm: max,
            });
        }
        Ok(samples)
    }
}
