//! Force fields: the physics' contact forces on each pad, spread over a grid on its sensing area
//! (FORMAT.md, `/tactile/<pad>/force`; the model in docs/tactile.md, "Force fields").
//!
//! - **Which forces**: the contacts on the pad's link that lie on its sensing area (within
//!   [`AREA_MARGIN`] of it) and face out of it; their sum is the pad's force.
//! - **Pressure**: the normal force spread over the cells as an elastic foundation (a Winkler
//!   layer) as thick as the contact threshold would spread it: in proportion to how far the object
//!   reaches into that layer at each pad pixel. Where the pad's view sees no contact pixel but
//!   the physics has a contact (a grazing touch), each contact's normal force goes to its cell.
//! - **Shear**: the tangential force spread as a rigid tangential shift of the contact against an
//!   elastic pad would spread it: the same traction in every cell, capped at each cell's Coulomb
//!   limit (friction × pressure); the cells at the cap slip, the rest stick (partial slip, as in
//!   Cattaneo–Mindlin: the lightly pressed rim slips first). The grid's forces sum to the pad's.

use glam::{DAffine3, DVec3};
use vt_dataset::{ForceCell, PadForceField};

use crate::physics::HandContact;

/// How far outside its sensing area (m, in the pad plane) a contact still counts for a pad: the
/// physics' contact points lie on the collision shape, which may stand out of the pad's outline.
pub const AREA_MARGIN: f64 = 1e-3;

/// A contact's normal must point within this angle of the pad's +z to press on the pad (60°).
const MIN_FACING: f64 = 0.5;

/// A physics contact as a pad sees it: the point and the force the object exerts there (N), in
/// the pad frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadContact {
    pub point: DVec3,
    pub force: DVec3,
}

/// The contacts of `contacts` (grasp frame) on the link `link` of a pad at `t_palm_pad` with
/// sensing area `size` (length, width; m): those on the sensing area, then the force of all of
/// them (pad frame).
pub fn pad_contacts(contacts: &[HandContact], link: usize, t_palm_pad: &DAffine3, size: (f64, f64)) -> (Vec<PadContact>, DVec3) {
    let to_pad = t_palm_pad.inverse();
    let mut on_area = Vec::new();
    let mut link_force = DVec3::ZERO;
    for c in contacts.iter().filter(|c| c.link == link) {
        let contact = PadContact { point: to_pad.transform_point3(c.point), force: to_pad.transform_vector3(c.force) };
        link_force += contact.force;
        let facing = to_pad.transform_vector3(c.normal).z >= MIN_FACING;
        let inside = contact.point.x.abs() <= size.0 / 2.0 + AREA_MARGIN && contact.point.y.abs() <= size.1 / 2.0 + AREA_MARGIN;
        if facing && inside {
            on_area.push(contact);
        }
    }
    (on_area, link_force)
}

/// What a pad's force field is made from.
pub struct PadTouch<'a> {
    pub pad: &'a str,
    /// The contacts on its sensing area (`pad_contacts`).
    pub contacts: &'a [PadContact],
    /// Per pad pixel (`n x n`, the pad camera's rows): the object's distance above the pad's
    /// surface (m), `+inf` where none is in range.
    pub gap: &'a [f32],
    pub n: u32,
    /// The contact threshold (m): the elastic layer's thickness.
    pub threshold: f64,
    /// The sensing area (length along x, width along y; m).
    pub size: (f64, f64),
    /// The friction coefficient of the contacts.
    pub friction: f64,
}

/// The pad's force field on a `resolution x resolution` grid (rows along the pad's y, as its
/// depth image).
pub fn force_field(touch: &PadTouch, resolution: u32) -> PadForceField {
    let r = resolution as usize;
    let (len, wid) = touch.size;
    let cell_area = (len / r as f64) * (wid / r as f64);
    let total: DVec3 = touch.contacts.iter().map(|c| c.force).sum();
    // The object pushes into the pad along -z.
    let normal = (-total.z).max(0.0);
    let weights = pressure_weights(touch, r);
    let loads: Vec<f64> = weights.iter().map(|w| normal * w).collect();
    let tangential = glam::DVec2::new(total.x, total.y);
    let caps: Vec<f64> = loads.iter().map(|l| touch.friction * l).collect();
    let (shares, slip) = shear_shares(&caps, tangential.length());
    let direction = tangential.normalize_or_zero();
    let cells = (0..r * r)
        .map(|i| {
            let (u, v) = (i % r, i / r);
            let at = |k: usize, extent: f64| ((k as f64 + 0.5 - r as f64 / 2.0) * extent / r as f64) as f32;
            ForceCell {
                position: [at(u, len), at(v, wid)],
                pressure: (loads[i] / cell_area) as f32,
                shear: (direction * shares[i] / cell_area).as_vec2().to_array(),
                slip: slip[i],
            }
        })
        .collect();
    PadForceField { pad: touch.pad.to_string(), resolution, cells }
}

/// Each cell's share (summing to 1, or all 0 without contact) of the pad's normal force.
fn pressure_weights(touch: &PadTouch, r: usize) -> Vec<f64> {
    let n = touch.n as usize;
    let mut w = vec![0.0; r * r];
    for (i, &g) in touch.gap.iter().enumerate() {
        let depth = touch.threshold - g as f64;
        if g.is_finite() && depth > 0.0 {
            let (u, v) = (i % n, i / n);
            w[(v * r / n) * r + u * r / n] += depth;
        }
    }
    if w.iter().sum::<f64>() <= 0.0 {
        // A grazing touch the pad's view misses: each contact's own cell.
        let (len, wid) = touch.size;
        let cell = |x: f64, extent: f64| (((x / extent + 0.5) * r as f64).floor().max(0.0) as usize).min(r - 1);
        for c in touch.contacts {
            w[cell(c.point.y, wid) * r + cell(c.point.x, len)] += (-c.force.z).max(0.0);
        }
    }
    let sum: f64 = w.iter().sum();
    if sum > 0.0 { w.iter().map(|x| x / sum).collect() } else { w }
}

/// How a tangential force `t` (N) spreads over cells whose friction limits are `caps` (N): one
/// traction for every cell, capped at its limit (those at it slip); the shares sum to `t`. When
/// `t` reaches the sum of the limits every loaded cell slips, in proportion to its limit (still
/// summing to `t`: the field keeps the physics' force even where its solver exceeds the limit).
pub fn shear_shares(caps: &[f64], t: f64) -> (Vec<f64>, Vec<bool>) {
    let mut shares = vec![0.0; caps.len()];
    let mut slip = vec![false; caps.len()];
    let limit: f64 = caps.iter().sum();
    if t <= 0.0 || limit <= 0.0 {
        return (shares, slip);
    }
    let loaded: Vec<usize> = (0..caps.len()).filter(|&i| caps[i] > 0.0).collect();
    // At the limit (to rounding) every loaded cell slips.
    if t >= limit * (1.0 - 1e-9) {
        for &i in &loaded {
            (shares[i], slip[i]) = (caps[i] * t / limit, true);
        }
        return (shares, slip);
    }
    // Fill from the weakest cell up: a cell whose limit is under the traction the rest would
    // carry slips at its limit.
    let mut order = loaded.clone();
    order.sort_by(|&a, &b| caps[a].total_cmp(&caps[b]));
    let (mut left, mut sticking) = (t, order.len());
    let mut first_stuck = order.len();
    for (k, &i) in order.iter().enumerate() {
        if caps[i] < left / sticking as f64 {
            (shares[i], slip[i]) = (caps[i], true);
            left -= caps[i];
            sticking -= 1;
        } else {
            first_stuck = k;
            break;
        }
    }
    let traction = left / sticking.max(1) as f64;
    for &i in &order[first_stuck..] {
        shares[i] = traction;
    }
    (shares, slip)
}

/// The tangential displacement of an elastic gel's surface under a pad's shear tractions: each
/// cell's shear force acting at its centre on an incompressible (ν = 1/2) elastic half-space,
/// superposed (Cerruti's solution, Johnson's *Contact Mechanics* eq. 2.19):
/// `u(p) = (Q + (Q·ρ̂) ρ̂) / (4π G ρ)` for a force Q at distance ρ, with ρ softened by half a cell
/// (`ρ² + a²/4`) so that a cell's own load stays finite. The surface moves along the traction the
/// object puts on it; the normal load moves it only along the normal (ν = 1/2).
#[derive(Debug, Clone, PartialEq)]
pub struct GelShear {
    /// Per loaded cell: its centre (pad frame, m) and its shear force (N).
    loads: Vec<([f64; 2], [f64; 2])>,
    shear_modulus: f64,
    core: f64,
}

impl GelShear {
    /// The displacement field of `field` (a pad whose sensing area is `size`) on a gel of shear
    /// modulus `shear_modulus` (Pa).
    pub fn new(field: &PadForceField, size: (f64, f64), shear_modulus: f64) -> Self {
        let r = field.resolution as f64;
        let (cell_x, cell_y) = (size.0 / r, size.1 / r);
        let loads = field
            .cells
            .iter()
            .filter(|c| c.shear != [0.0, 0.0])
            .map(|c| {
                ([c.position[0] as f64, c.position[1] as f64], [c.shear[0] as f64 * cell_x * cell_y, c.shear[1] as f64 * cell_x * cell_y])
            })
            .collect();
        GelShear { loads, shear_modulus, core: 0.5 * cell_x.min(cell_y) }
    }

    /// Whether no cell carries shear (the surface does not move).
    pub fn is_empty(&self) -> bool {
        self.loads.is_empty()
    }

    /// The surface's displacement (m, pad frame x and y) at `p` (pad frame, m).
    pub fn at(&self, p: [f64; 2]) -> [f64; 2] {
        let mut u = [0.0; 2];
        for &(c, q) in &self.loads {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let rho2 = dx * dx + dy * dy + self.core * self.core;
            let rho = rho2.sqrt();
            let along = (q[0] * dx + q[1] * dy) / rho2;
            let k = 1.0 / (4.0 * std::f64::consts::PI * self.shear_modulus * rho);
            u[0] += k * (q[0] + along * dx);
            u[1] += k * (q[1] + along * dy);
        }
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat 2 x 1 cm pad, 16 x 16 pixels, under a flat indenter `gap` above its plane (negative:
    /// pressed in) over the pixels `covered`, elsewhere out of range.
    fn flat(gap: f32, covered: impl Fn(u32, u32) -> bool) -> Vec<f32> {
        (0..16 * 16).map(|i| if covered(i % 16, i / 16) { gap } else { f32::INFINITY }).collect()
    }

    fn touch<'a>(contacts: &'a [PadContact], gap: &'a [f32]) -> PadTouch<'a> {
        PadTouch { pad: "pad", contacts, gap, n: 16, threshold: 0.002, size: (0.02, 0.01), friction: 0.8 }
    }

    fn sums(f: &PadForceField, size: (f64, f64)) -> DVec3 {
        let area = size.0 * size.1 / (f.resolution * f.resolution) as f64;
        f.cells.iter().map(|c| DVec3::new(c.shear[0] as f64, c.shear[1] as f64, -(c.pressure as f64)) * area).sum()
    }

    #[test]
    fn no_contact_gives_a_field_of_zeros() {
        let gap = flat(0.001, |_, _| true);
        let f = force_field(&touch(&[], &gap), 8);
        assert_eq!(f.cells.len(), 64);
        assert!(f.cells.iter().all(|c| c.pressure == 0.0 && c.shear == [0.0, 0.0] && !c.slip));
    }

    #[test]
    fn a_flat_press_spreads_evenly_and_sums_to_the_force() {
        let gap = flat(-0.0005, |_, _| true);
        let press = [PadContact { point: DVec3::ZERO, force: DVec3::new(0.0, 0.0, -4.0) }];
        let f = force_field(&touch(&press, &gap), 8);
        // 4 N over 2 cm²: 20 kPa everywhere.
        assert!(f.cells.iter().all(|c| (c.pressure - 20_000.0).abs() < 0.01), "{:?}", f.cells[0]);
        assert!((sums(&f, (0.02, 0.01)) - DVec3::new(0.0, 0.0, -4.0)).length() < 1e-6);
        // Cell centres as the pad camera's pixels: the first at (-L/2 + L/16, -W/2 + W/16).
        assert_eq!(f.cells[0].position, [-0.00875, -0.004375]);
    }

    /// The shear test: a flat indenter pressed with 4 N on the left half of the pad, the middle
    /// of it deeper (more pressure), then dragged along x with a growing force. Until the friction
    /// limit (0.8 × 4 N) the traction is the same in every sticking cell and the lightly pressed
    /// rim slips first; at the limit every cell slips; the field always sums to the force (past
    /// the limit too, which a solver should not give but the field must still sum to).
    #[test]
    fn a_dragged_indenter_sticks_then_slips_from_its_rim() {
        let gap: Vec<f32> =
            (0..256).map(|i| if i % 16 < 8 { if (6..10).contains(&(i / 16)) { -0.001 } else { 0.0 } } else { f32::INFINITY }).collect();
        let mut slipping_before = 0;
        for drag in [0.0, 0.4, 1.6, 3.0, 3.2, 4.0] {
            let contacts = [PadContact { point: DVec3::new(-0.005, 0.0, 0.0), force: DVec3::new(drag, 0.0, -4.0) }];
            let f = force_field(&touch(&contacts, &gap), 16);
            let total = sums(&f, (0.02, 0.01));
            assert!((total - DVec3::new(drag, 0.0, -4.0)).length() < 1e-5, "drag {drag}: {total}");
            let slipping = f.cells.iter().filter(|c| c.slip).count();
            assert!(slipping >= slipping_before, "drag {drag}: slip must grow with the drag");
            slipping_before = slipping;
            let pressed: Vec<&ForceCell> = f.cells.iter().filter(|c| c.pressure > 0.0).collect();
            assert_eq!(pressed.len(), 128, "only the indented half is pressed");
            assert!(f.cells.iter().all(|c| c.shear[1] == 0.0 && c.shear[0] >= 0.0));
            for c in pressed.iter().filter(|_| drag <= 3.2) {
                // Coulomb: no cell carries more than friction × pressure.
                assert!(c.shear[0] <= 0.8 * c.pressure * (1.0 + 1e-5), "drag {drag}: {c:?}");
            }
            match drag {
                0.0 => assert_eq!(slipping, 0),
                0.4 => {
                    // Below every cell's limit: one traction everywhere, nothing slips.
                    assert_eq!(slipping, 0);
                    let t = pressed[0].shear[0];
                    assert!(pressed.iter().all(|c| (c.shear[0] - t).abs() < 1e-3 * t));
                }
                3.0 => {
                    // Partial slip: the rim (lighter) slips, the deeper middle sticks.
                    assert!(slipping > 0 && slipping < 128, "{slipping} cells slip");
                    assert!(f.cells.iter().filter(|c| c.slip).all(|c| c.pressure < pressed.iter().map(|p| p.pressure).fold(0.0, f32::max)));
                }
                3.2 | 4.0 => assert_eq!(slipping, 128, "drag {drag}: at the friction limit all cells slip"),
                _ => {}
            }
        }
    }

    #[test]
    fn a_grazing_contact_the_view_misses_lands_in_its_cell() {
        let gap = flat(0.0, |_, _| false);
        let contacts = [PadContact { point: DVec3::new(0.0099, -0.0049, 0.0), force: DVec3::new(0.0, 0.0, -1.0) }];
        let f = force_field(&touch(&contacts, &gap), 4);
        let loaded: Vec<usize> = (0..16).filter(|&i| f.cells[i].pressure > 0.0).collect();
        // x near +L/2: column 3; y near -W/2: row 0.
        assert_eq!(loaded, vec![3]);
    }

    #[test]
    fn contacts_off_the_sensing_area_or_facing_away_do_not_count() {
        let pad = DAffine3::from_translation(DVec3::new(0.0, 0.0, 0.01));
        let c = |x: f64, nz: f64| HandContact {
            link: 3,
            point: DVec3::new(x, 0.0, 0.01),
            normal: DVec3::new(0.0, (1.0 - nz * nz).sqrt(), nz),
            force: DVec3::new(0.0, 0.0, -1.0),
        };
        let contacts = [c(0.0, 1.0), c(0.0105, 1.0), c(0.012, 1.0), c(0.0, -1.0), HandContact { link: 4, ..c(0.0, 1.0) }];
        let (on, link) = pad_contacts(&contacts, 3, &pad, (0.02, 0.01));
        assert_eq!(on.len(), 2, "the centre and within the margin");
        assert_eq!(link, DVec3::new(0.0, 0.0, -4.0));
    }
    /// One loaded cell against Cerruti's closed form for a point force on an incompressible
    /// half-space, far from the cell (where the softening is negligible).
    #[test]
    fn the_gel_shear_of_one_cell_is_cerrutis_point_load() {
        let mut cells = vec![ForceCell::default(); 4];
        cells[0] = ForceCell { position: [0.0, 0.0], pressure: 1.0, shear: [1000.0, 0.0], slip: false };
        let field = PadForceField { pad: "pad".into(), resolution: 2, cells };
        // 2 x 2 cells over 2 x 2 mm: 1 mm² each, so the cell's force is 1 mN along x.
        let shear = GelShear::new(&field, (0.002, 0.002), 50e3);
        let q = 1e-3;
        let g = 50e3;
        for p in [[0.02f64, 0.0], [0.0, 0.02], [0.014, 0.014]] {
            let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
            let ux = q / (2.0 * std::f64::consts::PI * g) * (0.5 / rho + 0.5 * p[0] * p[0] / rho.powi(3));
            let uy = q / (2.0 * std::f64::consts::PI * g) * (0.5 * p[0] * p[1] / rho.powi(3));
            let u = shear.at(p);
            assert!((u[0] - ux).abs() < 2e-3 * ux && (u[1] - uy).abs() < 2e-3 * ux.max(1e-12), "{p:?}: {u:?} vs ({ux}, {uy})");
        }
        // Finite at its own centre, along the load.
        let u = shear.at([0.0, 0.0]);
        assert!(u[0].is_finite() && u[0] > 0.0 && u[1] == 0.0);
    }
}
