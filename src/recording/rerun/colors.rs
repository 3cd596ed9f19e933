//! The colour scales of a recording: the rainbow of the mesh colour field and the red / blue
//! of contact gaps.

use re_sdk_types::components::Color;

/// Rainbow colour of `value / top` (blue at 0, cyan, green, yellow, red at 1), bright enough
/// on the viewer's dark background.
pub(super) fn colormap(value: f64, top: f64) -> Color {
    const STOPS: [[f64; 3]; 5] = [
        [40.0, 90.0, 255.0],
        [0.0, 200.0, 255.0],
        [40.0, 220.0, 80.0],
        [255.0, 220.0, 0.0],
        [230.0, 30.0, 30.0],
    ];
    let s = if top > 0.0 && value.is_finite() {
        (value / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = s * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    Color::from_rgb(c(0), c(1), c(2))
}

/// Red for penetration, blue for an open gap, stronger with |gap| / top.
pub(super) fn gap_color(gap: f64, top: f64) -> Color {
    let s = if top > 0.0 && gap.is_finite() {
        (gap.abs() / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let fade = (200.0 * (1.0 - s)) as u8;
    if gap < 0.0 {
        Color::from_rgb(230, fade, fade)
    } else {
        Color::from_rgb(fade, fade, 230)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_ends() {
        let blue = Color::from_rgb(40, 90, 255);
        assert_eq!(colormap(0.0, 1.0), blue);
        assert_eq!(colormap(2.0, 1.0), Color::from_rgb(230, 30, 30));
        assert_eq!(colormap(0.5, 1.0), Color::from_rgb(40, 220, 80));
        assert_eq!(colormap(f64::NAN, 1.0), blue);
        assert_eq!(colormap(1.0, 0.0), blue);
    }
}
