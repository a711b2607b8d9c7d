//! Body colours for files that carry them (the glTF export's materials): the browser viewer's
//! palette (`bodyColour` in web/src/render.ts), so that a body exported to Blender has the colour
//! it has in the viewer.

/// The viewer's body colours in turn (sRGB); the first is the classic jello's red.
const PALETTE: [u32; 7] = [
    0xe0405a, 0x43a047, 0xffb300, 0x1e88e5, 0x8e24aa, 0x00acc1, 0xf4511e,
];

/// Body `b`'s colour as linear RGB (each 0 to 1), what glTF's `baseColorFactor` holds: the
/// palette's in turn, then, as the viewer does, a hue of its own for each further body (the
/// golden angle apart, light and dark by turns).
pub fn body_colour(b: usize) -> [f32; 3] {
    let srgb = match PALETTE.get(b) {
        Some(&hex) => [16, 8, 0].map(|shift| ((hex >> shift) & 0xff) as f64 / 255.0),
        None => {
            let n = b - PALETTE.len();
            let hue = (0.13 + n as f64 * 0.381966) % 1.0;
            hsl_to_rgb(hue, 0.7, if n % 2 == 0 { 0.42 } else { 0.6 })
        }
    };
    srgb.map(|c| srgb_to_linear(c) as f32)
}

/// An sRGB component (0 to 1) as linear light, by the sRGB transfer function.
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Hue, saturation and lightness (each 0 to 1) as RGB, as three.js's `Color.setHSL` computes it.
fn hsl_to_rgb(h: f64, s: f64, l: f64) -> [f64; 3] {
    let q = if l <= 0.5 {
        l * (1.0 + s)
    } else {
        l + s - l * s
    };
    let p = 2.0 * l - q;
    let channel = |t: f64| {
        let t = t.rem_euclid(1.0);
        if t < 1.0 / 6.0 {
            p + (q - p) * 6.0 * t
        } else if t < 0.5 {
            q
        } else if t < 2.0 / 3.0 {
            p + (q - p) * 6.0 * (2.0 / 3.0 - t)
        } else {
            p
        }
    };
    [channel(h + 1.0 / 3.0), channel(h), channel(h - 1.0 / 3.0)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_palette_comes_first_in_linear_light_then_hues_of_their_own() {
        // 0xe0405a: sRGB (224, 64, 90) is linear (0.745, 0.0513, 0.102).
        let red = body_colour(0);
        for (got, want) in red.iter().zip([0.7454, 0.0513, 0.1022]) {
            assert!((got - want).abs() < 1e-3, "{red:?}");
        }
        // White and black stay themselves; grey 50 % sRGB is 21.4 % linear.
        assert_eq!(srgb_to_linear(1.0), 1.0);
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(0.5) - 0.2140).abs() < 1e-4);
        // HSL: pure red, and a grey without saturation.
        assert_eq!(hsl_to_rgb(0.0, 1.0, 0.5), [1.0, 0.0, 0.0]);
        assert_eq!(hsl_to_rgb(0.3, 0.0, 0.25), [0.25, 0.25, 0.25]);
        // Past the palette, every body differs from the ones before it.
        let colours: Vec<[f32; 3]> = (0..40).map(body_colour).collect();
        for (a, ca) in colours.iter().enumerate() {
            for cb in &colours[a + 1..] {
                assert_ne!(ca, cb);
            }
            assert!(ca.iter().all(|c| (0.0..=1.0).contains(c)), "{ca:?}");
        }
    }
}
