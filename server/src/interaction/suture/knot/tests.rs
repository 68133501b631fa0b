//! The knot reader on curves whose knots are known: torus knots, the figure-eight knot, connected sums, a
//! coiled unknot, seen from many directions; and open threads closed above the field.

use super::*;
use std::f64::consts::TAU;

/// The (p, q) torus knot on a torus of radii 20 and 10 mm about z, `samples` points (right-handed: seen from
/// +z its crossings are all positive, as the first test checks); `mirror` flips z.
fn torus_knot(p: f64, q: f64, samples: usize, mirror: bool) -> Vec<Vector3<f64>> {
    (0..samples)
        .map(|k| {
            let phi = TAU * k as f64 / samples as f64;
            let r = 20.0 + 10.0 * (q * phi).cos();
            let z = -10.0 * (q * phi).sin();
            Vector3::new(
                r * (p * phi).cos(),
                r * (p * phi).sin(),
                if mirror { -z } else { z },
            )
        })
        .collect()
}

fn figure_eight(samples: usize) -> Vec<Vector3<f64>> {
    (0..samples)
        .map(|k| {
            let t = TAU * k as f64 / samples as f64;
            let r = 20.0 + 10.0 * (2.0 * t).cos();
            Vector3::new(
                r * (3.0 * t).cos(),
                r * (3.0 * t).sin(),
                10.0 * (4.0 * t).sin(),
            )
        })
        .collect()
}

/// `a` and `b` (both centred near the origin) joined into one curve: `b` moved 100 mm along x, each opened
/// at its point nearest the other, and the ends bridged.
fn connected_sum(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let shift = Vector3::new(100.0, 0.0, 0.0);
    let b: Vec<_> = b.iter().map(|p| p + shift).collect();
    let extreme = |c: &[Vector3<f64>], sign: f64| {
        (0..c.len())
            .max_by(|&i, &j| (sign * c[i].x).total_cmp(&(sign * c[j].x)))
            .unwrap()
    };
    let (ia, ib) = (extreme(a, 1.0), extreme(&b, -1.0));
    let mut out = Vec::new();
    for k in 1..=a.len() {
        out.push(a[(ia + k) % a.len()]);
    }
    for k in 1..=b.len() {
        out.push(b[(ib + k) % b.len()]);
    }
    out
}

/// Directions spread over the upper half sphere (a golden-angle spiral), none of them exactly on an axis.
fn directions(n: usize) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|k| {
            let z = 1.0 - (k as f64 + 0.5) / n as f64 * 0.95;
            let r = (1.0 - z * z).sqrt();
            let a = k as f64 * 2.399_963;
            Vector3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

fn throws(single_right: u8, single_left: u8, double_right: u8, double_left: u8) -> KnotKind {
    KnotKind::Throws(Throws {
        single_right,
        single_left,
        double_right,
        double_left,
    })
}

/// Reads `curve` from every direction of [`directions`]; all must agree on `expected`.
fn read_everywhere(curve: &[Vector3<f64>], expected: KnotKind) {
    let mut reader = KnotReader::new();
    for d in directions(24) {
        let kind = reader.read_closed(curve, d).unwrap();
        assert_eq!(
            kind,
            expected,
            "seen from {d:?} ({} crossings)",
            reader.crossings()
        );
    }
}

#[test]
fn a_right_handed_diagram_has_the_right_handed_trefoils_polynomial() {
    // The (2, 3) torus knot seen from +z: three crossings, all positive. The state sum's convention is right
    // if, and only if, that diagram gives t + t^3 - t^4 (a knot whose reduced diagram is all positive is
    // right-handed), and its mirror the mirrored polynomial.
    let mut d = Diagram::new();
    d.project(&torus_knot(2.0, 3.0, 90, false), Vector3::z())
        .unwrap();
    d.simplify();
    assert_eq!(d.signs(), &[1, 1, 1]);
    assert_eq!(bracket::jones(&d).unwrap(), trefoil_right());
    d.project(&torus_knot(2.0, 3.0, 90, true), Vector3::z())
        .unwrap();
    d.simplify();
    assert_eq!(d.signs(), &[-1, -1, -1]);
    assert_eq!(bracket::jones(&d).unwrap(), trefoil_right().mirrored());
    // The (2, 5) torus knot: its catalogued polynomial is the one the state sum gives.
    d.project(&torus_knot(2.0, 5.0, 150, false), Vector3::z())
        .unwrap();
    d.simplify();
    assert_eq!(d.crossings(), 5);
    assert_eq!(bracket::jones(&d).unwrap(), cinquefoil_right());
}

#[test]
fn single_and_double_throws_read_alike_from_every_side() {
    read_everywhere(&torus_knot(2.0, 3.0, 120, false), throws(1, 0, 0, 0));
    read_everywhere(&torus_knot(2.0, 3.0, 120, true), throws(0, 1, 0, 0));
    read_everywhere(&torus_knot(2.0, 5.0, 200, false), throws(0, 0, 1, 0));
}

#[test]
fn square_granny_and_surgeons_knots_are_told_apart() {
    let right = torus_knot(2.0, 3.0, 90, false);
    let left = torus_knot(2.0, 3.0, 90, true);
    let double_right = torus_knot(2.0, 5.0, 150, false);
    let square = connected_sum(&right, &left);
    read_everywhere(&square, throws(1, 1, 0, 0));
    let granny = connected_sum(&right, &right);
    read_everywhere(&granny, throws(2, 0, 0, 0));
    let surgeons = connected_sum(&double_right, &left);
    read_everywhere(&surgeons, throws(0, 1, 1, 0));
    let names = |k: KnotKind| match k {
        KnotKind::Throws(t) => (t.name(), t.can_alternate()),
        other => panic!("{other:?}"),
    };
    assert_eq!(names(throws(1, 1, 0, 0)), ("square knot".to_owned(), true));
    assert_eq!(names(throws(0, 2, 0, 0)), ("granny knot".to_owned(), false));
    assert_eq!(
        names(throws(0, 1, 1, 0)),
        ("surgeon's knot".to_owned(), true)
    );
    assert_eq!(names(throws(1, 0, 0, 0)), ("half knot".to_owned(), true));
    assert_eq!(names(throws(2, 1, 0, 0)), ("3 throws".to_owned(), true));
}

#[test]
fn a_figure_eight_is_a_knot_but_not_of_throws() {
    // Four crossings at the least; a view may keep more (the reader stops looking once the bracket can sum).
    let mut reader = KnotReader::new();
    for d in directions(24) {
        let kind = reader.read_closed(&figure_eight(160), d).unwrap();
        assert!(
            matches!(kind, KnotKind::Other { crossings } if crossings >= 4),
            "seen from {d:?}: {kind:?}"
        );
    }
}

#[test]
fn a_coil_wound_and_unwound_ties_nothing() {
    // A helix of four turns up, then back down along a wider helix, closed: dozens of crossings from most
    // directions, no knot.
    let mut curve = Vec::new();
    for k in 0..200 {
        let a = TAU * 4.0 * f64::from(k) / 200.0;
        curve.push(Vector3::new(
            10.0 * a.cos(),
            10.0 * a.sin(),
            f64::from(k) * 0.2,
        ));
    }
    for k in (0..200).rev() {
        let a = TAU * 4.0 * f64::from(k) / 200.0 + 0.3;
        curve.push(Vector3::new(
            14.0 * a.cos(),
            14.0 * a.sin(),
            f64::from(k) * 0.2 + 0.5,
        ));
    }
    let mut reader = KnotReader::new();
    let mut most = 0;
    for d in directions(24) {
        let mut raw = Diagram::new();
        raw.project(&curve, d).unwrap();
        most = most.max(raw.crossings());
        assert_eq!(
            reader.read_closed(&curve, d).unwrap(),
            KnotKind::None,
            "from {d:?}"
        );
    }
    assert!(most >= 8, "the coil crossed itself only {most} times");
}

#[test]
fn too_many_crossings_are_tangled_not_guessed() {
    let mut reader = KnotReader::new();
    assert_eq!(
        reader
            .read_closed(&torus_knot(2.0, 13.0, 520, false), Vector3::z())
            .unwrap(),
        KnotKind::Tangled { crossings: 13 }
    );
}

/// An open thread, as a stitch leaves it: in at the right hole (x = +5 mm), under the wound, out at the left
/// hole (x = -5 mm), and its two strands twisted `half_twists` half turns about each other along the line
/// across the wound (the x axis, 6 mm up), the way a tightened throw lies on the wound; then each end led up
/// and off to a hand. `hands` (+1 or -1) is the twist's sense. One throw is three half turns, a surgeon's
/// double throw five.
fn tied_stitch(hands: f64, half_twists: f64) -> Vec<Vec3> {
    const L_MM: f64 = 8.0;
    // A strand of the twist from its right end (s = 0) to its left end (s = 1), starting at angle `from`
    // about the axis (-pi/2: below it, pi/2: above).
    let strand = |from: f64| -> Vec<Vec3> {
        (0..=40)
            .map(|k| {
                let s = f64::from(k) / 40.0;
                let a = from + hands * half_twists * std::f64::consts::PI * s;
                Vec3::new(
                    (L_MM - 2.0 * L_MM * s) as f32,
                    (3.0 * a.cos()) as f32,
                    (6.0 + 3.0 * a.sin()) as f32,
                )
            })
            .collect()
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut nodes = vec![Vec3::new(40.0, 0.0, 30.0)]; // the needle's end, in the right hand
    nodes.extend(strand(half_pi)); // in at the top right end of the twist, out at its far end
    let out_end = *nodes.last().unwrap();
    // Down into the left hole, under the wound, up out of the right hole.
    nodes.push(Vec3::new(out_end.x, out_end.y, 1.0));
    nodes.push(Vec3::new(-5.0, 0.0, 0.0));
    nodes.push(Vec3::new(-3.0, 0.0, -4.0));
    nodes.push(Vec3::new(3.0, 0.0, -4.0));
    nodes.push(Vec3::new(5.0, 0.0, 0.0));
    let other = strand(-half_pi);
    nodes.push(Vec3::new(other[0].x, other[0].y, 1.0));
    nodes.extend(other);
    nodes.push(Vec3::new(-40.0, 0.0, 25.0)); // the free end, in the left hand
    nodes
}

#[test]
fn a_throw_between_a_stitchs_two_ends_reads_as_a_half_knot_and_its_hand() {
    let mut reader = KnotReader::new();
    let up = Vec3::z();
    let right = reader.read_thread(&tied_stitch(1.0, 3.0), up).unwrap();
    let left = reader.read_thread(&tied_stitch(-1.0, 3.0), up).unwrap();
    let (KnotKind::Throws(r), KnotKind::Throws(l)) = (right, left) else {
        panic!("{right:?} {left:?}");
    };
    assert_eq!((r.count(), l.count()), (1, 1));
    assert_ne!(r, l, "the two hands read alike");
    assert_eq!(r.name(), "half knot");
    // A double throw: the surgeon's.
    let KnotKind::Throws(double) = reader.read_thread(&tied_stitch(1.0, 5.0), up).unwrap() else {
        panic!("a double throw is not a knot of throws");
    };
    assert_eq!(double.name(), "surgeon's throw");
    // The ends only crossed (one half turn), or not at all, or wound about each other along the vertical
    // (as the thread is when one end is merely turned about the other): nothing.
    assert_eq!(
        reader.read_thread(&tied_stitch(1.0, 1.0), up).unwrap(),
        KnotKind::None
    );
    assert_eq!(
        reader.read_thread(&tied_stitch(1.0, 0.0), up).unwrap(),
        KnotKind::None
    );
    // Read from the thread's other end: the same knot.
    let mut reversed = tied_stitch(1.0, 3.0);
    reversed.reverse();
    assert_eq!(reader.read_thread(&reversed, up).unwrap(), right);
}

#[test]
fn a_thread_that_is_not_finite_is_refused() {
    let mut reader = KnotReader::new();
    let mut nodes = tied_stitch(1.0, 3.0);
    nodes[3].x = f32::NAN;
    assert_eq!(
        reader.read_thread(&nodes, Vec3::z()),
        Err(DiagramError::BadCurve)
    );
    assert_eq!(
        reader.read_thread(&tied_stitch(1.0, 3.0), Vec3::zeros()),
        Err(DiagramError::BadCurve)
    );
}

/// The free end of a tied stitch hanging down under the throw, so that the way straight up from it runs through
/// the throw: closed that way alone the thread reads as no knot (or another), but the closures' vote
/// (`read_thread`) reads the throw, as with the end held up.
#[test]
fn a_free_end_hanging_under_the_throw_does_not_undo_its_reading() {
    let mut reader = KnotReader::new();
    let up = Vec3::z();
    let held_up = reader.read_thread(&tied_stitch(1.0, 3.0), up).unwrap();
    assert!(matches!(held_up, KnotKind::Throws(t) if t.name() == "half knot"));
    for end in [
        Vec3::new(0.0, 0.0, -8.0),
        Vec3::new(2.0, 1.0, -8.0),
        Vec3::new(-2.0, -1.0, -8.0),
        Vec3::new(4.0, 0.5, -8.0),
    ] {
        let mut nodes = tied_stitch(1.0, 3.0);
        nodes.push(Vec3::new(-20.0, 15.0, -10.0));
        nodes.push(end);
        // Closed straight up alone (the reader's own closure, read as `read_closed` reads).
        reader.closed.clear();
        reader.closed.extend(nodes.iter().map(|p| p.cast::<f64>()));
        reader.close_along(nodes.len(), Vector3::z());
        let closed = reader.closed.clone();
        let straight_up = reader.read_closed(&closed, Vector3::z()).unwrap();
        assert_ne!(
            straight_up, held_up,
            "end at {end:?}: one closure read it right"
        );
        assert_eq!(
            reader.read_thread(&nodes, up).unwrap(),
            held_up,
            "end at {end:?}: the vote missed the throw"
        );
    }
}
