use super::*;
use proptest::prelude::*;

// ---------------------------------------------------------------- helpers

/// Canonical form of straight RGBA8: a fully transparent pixel carries no colour.
fn canonical(image: &RgbaImage) -> RgbaImage {
    let mut out = image.clone();
    for px in out.data.chunks_mut(4) {
        if px[3] == 0 {
            px.copy_from_slice(&[0, 0, 0, 0]);
        }
    }
    out
}

fn alpha_matte(image: &RgbaImage) -> Grid {
    let matte: Vec<u8> = image.data.chunks(4).map(|p| p[3]).collect();
    Grid::from_matte(image.width, image.height, &matte)
}

fn field_from(width: usize, height: usize, f: impl Fn(f64, f64) -> [f64; 2]) -> Field {
    let mut field = Field::zeros(width, height);
    for y in 0..height {
        for x in 0..width {
            let d = f(x as f64, y as f64);
            field.dx[y * width + x] = d[0] as f32;
            field.dy[y * width + x] = d[1] as f32;
        }
    }
    field
}

fn constant_field(width: usize, height: usize, t: [f64; 2]) -> Field {
    field_from(width, height, |_, _| t)
}

/// Deterministic pseudo-random bytes (a 64-bit LCG), for images in plain unit tests.
fn noise(seed: u64, n: usize) -> Vec<u8> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 56) as u8
        })
        .collect()
}

fn opaque_noise(width: usize, height: usize, seed: u64) -> RgbaImage {
    let mut data = noise(seed, width * height * 4);
    for px in data.chunks_mut(4) {
        px[3] = 255;
    }
    RgbaImage::from_raw(width, height, data).unwrap()
}

fn solid(width: usize, height: usize, rgba: [u8; 4]) -> RgbaImage {
    RgbaImage::from_raw(width, height, rgba.repeat(width * height)).unwrap()
}

/// The exact area-weighted image of `image` translated by `t` onto a canvas: each source
/// pixel is a unit square of constant premultiplied colour (nonzero alpha only).
fn box_reference(image: &RgbaImage, t: [f64; 2], cw: usize, ch: usize) -> RgbaImage {
    let mut out = RgbaImage::new(cw, ch);
    for oy in 0..ch {
        for ox in 0..cw {
            let mut acc = [0.0f64; 4];
            for y in 0..image.height {
                let ov_y = (oy as f64 + 0.5).min(y as f64 + t[1] + 0.5)
                    - (oy as f64 - 0.5).max(y as f64 + t[1] - 0.5);
                if ov_y <= 0.0 {
                    continue;
                }
                for x in 0..image.width {
                    let ov_x = (ox as f64 + 0.5).min(x as f64 + t[0] + 0.5)
                        - (ox as f64 - 0.5).max(x as f64 + t[0] - 0.5);
                    if ov_x <= 0.0 {
                        continue;
                    }
                    let px = image.pixel(x, y);
                    if px[3] == 0 {
                        continue;
                    }
                    let a = px[3] as f64 / 255.0;
                    let w = ov_x * ov_y;
                    for c in 0..3 {
                        acc[c] += w * px[c] as f64 / 255.0 * a;
                    }
                    acc[3] += w * a;
                }
            }
            let p = unpremultiply([acc[0] as f32, acc[1] as f32, acc[2] as f32, acc[3] as f32]);
            let i = (oy * cw + ox) * 4;
            out.data[i..i + 4].copy_from_slice(&p);
        }
    }
    out
}

/// The largest difference per channel of straight RGBA8. Where one side's alpha rounds
/// to 0 (so its colour is the canonical zero) only the alphas are compared: a true alpha
/// near 0.5/255 may round either way, and its colour is then meaningless.
fn max_channel_diff(a: &RgbaImage, b: &RgbaImage) -> u8 {
    a.data
        .chunks(4)
        .zip(b.data.chunks(4))
        .map(|(p, q)| {
            if p[3] == 0 || q[3] == 0 {
                p[3].abs_diff(q[3])
            } else {
                p.iter()
                    .zip(q)
                    .map(|(&x, &y)| x.abs_diff(y))
                    .max()
                    .unwrap_or(0)
            }
        })
        .max()
        .unwrap_or(0)
}

fn render(
    image: &RgbaImage,
    field: &Field,
    grid: &Grid,
    cw: usize,
    ch: usize,
    offset: [f64; 2],
) -> RgbaImage {
    let mut canvas = Canvas::new(cw, ch, [0; 4]);
    canvas.draw_layer(image, field, grid, offset);
    canvas.to_rgba8()
}

// ---------------------------------------------------------------- strategies

prop_compose! {
    /// An RGBA image with some fully transparent pixels (holes), colour zero where alpha is.
    fn rgba_image(max: usize)(w in 1..=max, h in 1..=max)
        (data in proptest::collection::vec((any::<[u8; 3]>(), prop_oneof![Just(0u8), Just(255u8), 1u8..=255]), w * h), w in Just(w), h in Just(h))
        -> RgbaImage {
        let data = data.into_iter().flat_map(|(c, a)| if a == 0 { [0, 0, 0, 0] } else { [c[0], c[1], c[2], a] }).collect();
        RgbaImage::from_raw(w, h, data).unwrap()
    }
}

prop_compose! {
    /// A grid from a random matte, with some links broken at random (cuts).
    fn random_grid(w: usize, h: usize)(active in proptest::collection::vec(prop::bool::weighted(0.85), w * h),
                                       cut_r in proptest::collection::vec(prop::bool::weighted(0.15), w * h),
                                       cut_d in proptest::collection::vec(prop::bool::weighted(0.15), w * h)) -> Grid {
        let matte: Vec<u8> = active.iter().map(|&a| a as u8).collect();
        let mut g = Grid::from_matte(w, h, &matte);
        for i in 0..w * h {
            g.link_right[i] &= !cut_r[i];
            g.link_down[i] &= !cut_d[i];
        }
        g
    }
}

// ---------------------------------------------------------------- properties

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// The identity field reproduces the layer byte for byte, whatever the matte and cuts.
    #[test]
    fn identity_reproduces_the_layer(
        (image, grid) in rgba_image(14).prop_flat_map(|im| { let (w, h) = (im.width, im.height); (Just(im), random_grid(w, h)) })
    ) {
        let out = try_warp_image(&image, &Field::zeros(image.width, image.height), &grid).unwrap();
        prop_assert_eq!(out, canonical(&image));
    }

    /// An integer translation shifts the layer exactly (pixels pushed off the canvas are lost).
    #[test]
    fn integer_translation_shifts_exactly(image in rgba_image(12), tx in -5i32..=5, ty in -5i32..=5) {
        let (w, h) = (image.width, image.height);
        let (cw, ch) = (w + 4, h + 4);
        let out = render(&image, &constant_field(w, h, [tx as f64, ty as f64]), &alpha_matte(&image), cw, ch, [2.0, 2.0]);
        let expected = canonical(&render_shift(&image, tx + 2, ty + 2, cw, ch));
        prop_assert_eq!(out, expected);
    }

    /// A sub-pixel translation is the exact box-filtered image, to one level per channel,
    /// borders and holes included.
    #[test]
    fn subpixel_translation_matches_the_area_weighted_reference(
        image in rgba_image(10), tx in -1.5f64..1.5, ty in -1.5f64..1.5,
    ) {
        let (w, h) = (image.width, image.height);
        let (cw, ch) = (w + 4, h + 4);
        let out = render(&image, &constant_field(w, h, [tx, ty]), &alpha_matte(&image), cw, ch, [2.0, 2.0]);
        let reference = box_reference(&image, [tx + 2.0, ty + 2.0], cw, ch);
        prop_assert!(max_channel_diff(&out, &reference) <= 1, "max diff {}", max_channel_diff(&out, &reference));
    }

    /// A layer offset is the same as a constant field.
    #[test]
    fn offset_equals_translation(image in rgba_image(8), ox in -2.0f64..2.0, oy in -2.0f64..2.0) {
        let (w, h) = (image.width, image.height);
        let grid = alpha_matte(&image);
        let a = render(&image, &Field::zeros(w, h), &grid, w + 4, h + 4, [ox + 2.0, oy + 2.0]);
        let b = render(&image, &constant_field(w, h, [ox, oy]), &grid, w + 4, h + 4, [2.0, 2.0]);
        prop_assert!(max_channel_diff(&a, &b) <= 1);
    }

    /// A rigid rotation of an opaque layer leaves no crack inside it and keeps its area.
    #[test]
    fn rotation_has_no_cracks(angle in -3.2f64..3.2, seed in any::<u64>()) {
        let (w, h) = (24, 18);
        let image = opaque_noise(w, h, seed);
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let (s, c) = angle.sin_cos();
        let field = field_from(w, h, |x, y| {
            let (u, v) = (x - cx, y - cy);
            [c * u - s * v - u, s * u + c * v - v]
        });
        let (cw, ch) = (40, 40);
        let offset = [(cw as f64 - w as f64) / 2.0, (ch as f64 - h as f64) / 2.0];
        let out = render(&image, &field, &Grid::new(w, h), cw, ch, offset);
        let mut alpha_sum = 0.0;
        for oy in 0..ch {
            for ox in 0..cw {
                let a = out.pixel(ox, oy)[3];
                alpha_sum += a as f64 / 255.0;
                // Preimage of the centre in the rest image.
                let (u, v) = (ox as f64 - offset[0] - cx, oy as f64 - offset[1] - cy);
                let (x, y) = (c * u + s * v + cx, -s * u + c * v + cy);
                // Centres whose unit square (radius ≤ √½) lies inside the rest rectangle.
                let margin = 0.75;
                if x > -0.5 + margin && x < w as f64 - 0.5 - margin && y > -0.5 + margin && y < h as f64 - 0.5 - margin {
                    prop_assert_eq!(a, 255, "crack at ({}, {})", ox, oy);
                }
            }
        }
        // Rotation keeps area: the coverage adds up to the layer's pixel count.
        prop_assert!((alpha_sum - (w * h) as f64).abs() < 0.01 * (w * h) as f64, "area {} vs {}", alpha_sum, w * h);
    }
}

/// `image` shifted by an integer amount onto a transparent canvas.
fn render_shift(image: &RgbaImage, tx: i32, ty: i32, cw: usize, ch: usize) -> RgbaImage {
    let mut out = RgbaImage::new(cw, ch);
    for y in 0..image.height {
        for x in 0..image.width {
            let (ox, oy) = (x as i32 + tx, y as i32 + ty);
            if ox >= 0 && oy >= 0 && (ox as usize) < cw && (oy as usize) < ch {
                let i = (oy as usize * cw + ox as usize) * 4;
                out.data[i..i + 4].copy_from_slice(&image.pixel(x, y));
            }
        }
    }
    out
}

// ---------------------------------------------------------------- unit tests

#[test]
fn identity_on_a_large_opaque_image_is_exact() {
    let image = opaque_noise(67, 45, 7);
    assert_eq!(
        try_warp_image(&image, &Field::zeros(67, 45), &Grid::new(67, 45)).unwrap(),
        image
    );
}

#[test]
fn a_held_edge_stays_on_the_frame_however_the_picture_is_squeezed_toward_it() {
    // The picture pushed toward its held edges (the field vanishes on every edge pixel and
    // squeezes the last rows and columns to 0.6 of a pixel): the outer half-pixel of
    // an edge pixel was half the squeezed link, and the background showed along the edge.
    let (w, h) = (24, 20);
    let bump = |t: f64, n: f64| 0.4 * t * (1.0 - t / n);
    let field = field_from(w, h, |x, y| [bump(x, (w - 1) as f64), bump(y, (h - 1) as f64)]);
    assert!(field.dy[(h - 2) * w + 5] > 0.35 && field.dy[(h - 1) * w + 5] == 0.0 && field.dx[5 * w + w - 1] == 0.0);
    let out = render(&solid(w, h, [10, 200, 30, 255]), &field, &Grid::new(w, h), w, h, [0.0, 0.0]);
    assert!(out.data.chunks(4).all(|p| p[3] == 255), "the layer still covers the whole frame");
    // Held to rounding only (an exact solve's 1e-13 px), and at an offset: the same.
    let nudged = field_from(w, h, |x, y| [bump(x, (w - 1) as f64) + 1e-7, bump(y, (h - 1) as f64) - 1e-7]);
    let out = render(&solid(w, h, [10, 200, 30, 255]), &nudged, &Grid::new(w, h), w + 6, h + 6, [3.0, 3.0]);
    assert!((3..3 + h).all(|y| (3..3 + w).all(|x| out.pixel(x, y)[3] == 255)), "held to rounding, the layer covers its frame");
    // A layer that moves keeps the rule it had: its edge goes with it.
    let moved = render(&solid(w, h, [10, 200, 30, 255]), &constant_field(w, h, [0.0, -0.5]), &Grid::new(w, h), w, h, [0.0, 0.0]);
    assert_eq!(moved.pixel(3, h - 1)[3], 128);
}

#[test]
fn sine_warp_has_no_cracks() {
    let (w, h) = (64, 48);
    let image = opaque_noise(w, h, 3);
    let (amp, period) = (3.0, 24.0);
    let tau = std::f64::consts::TAU;
    let warp = |x: f64, y: f64| {
        [
            x + amp * (tau * y / period).sin(),
            y + amp * (tau * x / period).sin(),
        ]
    };
    let field = field_from(w, h, |x, y| {
        let p = warp(x, y);
        [p[0] - x, p[1] - y]
    });
    let (cw, ch) = (w + 10, h + 10);
    let out = render(&image, &field, &Grid::new(w, h), cw, ch, [5.0, 5.0]);
    // Inverse of the warp by Newton's method.
    let unwarp = |target: [f64; 2]| {
        let mut p = target;
        for _ in 0..50 {
            let f = warp(p[0], p[1]);
            let (r0, r1) = (f[0] - target[0], f[1] - target[1]);
            let b = amp * tau / period * (tau * p[1] / period).cos();
            let c = amp * tau / period * (tau * p[0] / period).cos();
            let det = 1.0 - b * c;
            p = [p[0] - (r0 - b * r1) / det, p[1] - (-c * r0 + r1) / det];
        }
        p
    };
    let inside = |p: [f64; 2]| {
        p[0] > -0.45 && p[0] < w as f64 - 0.55 && p[1] > -0.45 && p[1] < h as f64 - 0.55
    };
    let mut checked = 0;
    for oy in 0..ch {
        for ox in 0..cw {
            // Pixels whose whole unit square maps back inside the rest rectangle.
            let corners = [
                [-0.5, -0.5],
                [0.5, -0.5],
                [0.5, 0.5],
                [-0.5, 0.5],
                [0.0, 0.0],
            ];
            if corners
                .iter()
                .all(|d| inside(unwarp([ox as f64 - 5.0 + d[0], oy as f64 - 5.0 + d[1]])))
            {
                assert_eq!(out.pixel(ox, oy)[3], 255, "crack at ({ox}, {oy})");
                checked += 1;
            }
        }
    }
    assert!(checked > 2000);
}

#[test]
fn a_cut_opens_when_the_field_pulls_it_apart() {
    let (w, h) = (20, 10);
    let image = solid(w, h, [200, 30, 30, 255]);
    // Left half moves 2 px left, right half 2 px right: a 4 px gap where the links are cut.
    let field = field_from(w, h, |x, _| [if x < 10.0 { -2.0 } else { 2.0 }, 0.0]);
    let mut cut = Grid::new(w, h);
    for y in 0..h {
        cut.link_right[y * w + 9] = false;
    }
    let out = render(&image, &field, &cut, w + 8, h, [4.0, 0.0]);
    for y in 0..h {
        let row: Vec<u8> = (0..w + 8).map(|x| out.pixel(x, y)[3]).collect();
        // Left piece ends at 9.5 - 2 + 4 = 11.5, right piece starts at 9.5 + 2 + 4 = 15.5.
        assert_eq!(&row[2..12], &[255; 10], "row {y}");
        assert_eq!(&row[12..16], &[0; 4], "row {y}: the cut must open");
        assert_eq!(&row[16..26], &[255; 10], "row {y}");
    }
    // The same field without the cut stretches the middle quad: no gap.
    let joined = render(&image, &field, &Grid::new(w, h), w + 8, h, [4.0, 0.0]);
    for y in 0..h {
        for x in 2..26 {
            assert_eq!(joined.pixel(x, y)[3], 255, "({x}, {y})");
        }
    }
}

#[test]
fn a_hole_opens_when_the_field_pulls_it_apart() {
    let (w, h) = (24, 24);
    // Opaque square with a 4×4 transparent hole in the middle (rows and columns 10..14).
    let mut image = solid(w, h, [20, 120, 220, 255]);
    for y in 10..14 {
        for x in 10..14 {
            let i = (y * w + x) * 4;
            image.data[i..i + 4].copy_from_slice(&[0, 0, 0, 0]);
        }
    }
    let grid = alpha_matte(&image);
    // Everything left of the hole's centre moves left by 3, everything right of it right
    // by 3, smoothly across a band above and below, pulling the hole's sides apart.
    let field = field_from(w, h, |x, _| {
        [3.0 * ((x - 11.5) / 2.0).clamp(-1.0, 1.0), 0.0]
    });
    let out = render(&image, &field, &grid, w, h, [0.0, 0.0]);
    // Hole rows: the gap now spans 9.5 - 3 .. 14.5 + 3, i.e. pixels 7..=16 are clear.
    for y in 11..13 {
        for x in 7..=16 {
            assert_eq!(
                out.pixel(x, y)[3],
                0,
                "({x}, {y}) should be in the opened hole"
            );
        }
    }
    // Rows away from the hole are stretched, not torn.
    for x in 0..w {
        assert_eq!(out.pixel(x, 3)[3], 255, "({x}, 3)");
    }
}

#[test]
fn fold_overs_put_the_later_rest_pixels_in_front() {
    // Columns 12.. move 8 px left, over columns 4..12: the mesh folds between 11 and 12.
    let (w, h) = (24, 8);
    let mut image = solid(w, h, [255, 0, 0, 255]);
    for y in 0..h {
        for x in 12..w {
            let i = (y * w + x) * 4;
            image.data[i..i + 4].copy_from_slice(&[0, 0, 255, 255]);
        }
    }
    let field = field_from(w, h, |x, _| [if x >= 12.0 { -8.0 } else { 0.0 }, 0.0]);
    let out = render(&image, &field, &Grid::new(w, h), w, h, [0.0, 0.0]);
    for y in 0..h {
        for x in 4..16 {
            assert_eq!(
                out.pixel(x, y),
                [0, 0, 255, 255],
                "({x}, {y}): the right part is in front"
            );
        }
        for x in 0..4 {
            assert_eq!(out.pixel(x, y), [255, 0, 0, 255], "({x}, {y})");
        }
    }
}

#[test]
fn a_translucent_part_in_front_shows_what_lies_behind_it() {
    // An opaque square moves right over a translucent pixel (alpha 128) of the same layer
    // that stays put: the pixel is drawn later, so it is in front, but over the square, not
    // in its place (a faint fringe pixel, alpha 3, punched a see-through hole in it).
    let (w, h) = (24, 16);
    let mut image = solid(w, h, [0, 0, 0, 0]);
    let set = |image: &mut RgbaImage, x: usize, y: usize, p: [u8; 4]| image.data[(y * w + x) * 4..][..4].copy_from_slice(&p);
    (4..12).for_each(|y| (2..10).for_each(|x| set(&mut image, x, y, [200, 120, 60, 255])));
    set(&mut image, 14, 8, [0, 0, 250, 128]);
    let field = field_from(w, h, |x, y| [if (2.0..10.0).contains(&x) && (4.0..12.0).contains(&y) { 9.0 } else { 0.0 }, 0.0]);
    let out = render(&image, &field, &alpha_matte(&image), w, h, [0.0, 0.0]);
    for x in 11..19 {
        let p = out.pixel(x, 8);
        assert_eq!(p[3], 255, "({x}, 8): the square covers it");
        if x != 14 {
            assert_eq!(p, [200, 120, 60, 255], "({x}, 8)");
        }
    }
    // At the fringe pixel: half its blue over the square's orange.
    let [r, g, b, _] = out.pixel(14, 8);
    assert!((r as i32 - 100).abs() <= 1 && (g as i32 - 60).abs() <= 1 && (b as i32 - 155).abs() <= 1, "{:?}", [r, g, b]);
}

#[test]
fn a_flap_folded_back_over_its_piece_stays_covered() {
    // The last 8 columns are mirrored back over the piece: the folded flap and the sheet
    // under it have opposite orientations, and the flap must still cover.
    let (w, h) = (32, 8);
    let image = opaque_noise(w, h, 11);
    let field = field_from(w, h, |x, _| {
        [if x > 23.0 { 2.0 * (23.0 - x) } else { 0.0 }, 0.0]
    });
    let out = render(&image, &field, &Grid::new(w, h), w, h, [0.0, 0.0]);
    for y in 0..h {
        for x in 0..=23 {
            assert_eq!(out.pixel(x, y)[3], 255, "({x}, {y})");
        }
        for x in 24..w {
            assert_eq!(out.pixel(x, y)[3], 0, "({x}, {y})");
        }
        // The flap (rest columns 24..31, now at 22..15) is in front of the sheet.
        for x in 17..=22 {
            assert_eq!(
                out.pixel(x, y),
                image.pixel(46 - x, y),
                "({x}, {y}) shows the flap"
            );
        }
    }
}

#[test]
fn layers_composite_back_to_front_over_the_background() {
    let mut canvas = Canvas::new(4, 1, [0, 0, 0, 255]);
    let red = solid(3, 1, [255, 0, 0, 255]);
    let half_blue = solid(3, 1, [0, 0, 255, 128]);
    canvas.draw_layer(&red, &Field::zeros(3, 1), &Grid::new(3, 1), [0.0, 0.0]);
    canvas.draw_layer(
        &half_blue,
        &Field::zeros(3, 1),
        &Grid::new(3, 1),
        [1.0, 0.0],
    );
    let out = canvas.to_rgba8();
    assert_eq!(out.pixel(0, 0), [255, 0, 0, 255]);
    // Blue at alpha 128/255 over red: 127 red, 128 blue.
    assert_eq!(out.pixel(1, 0), [127, 0, 128, 255]);
    assert_eq!(out.pixel(2, 0), [127, 0, 128, 255]);
    // Over the black background.
    assert_eq!(out.pixel(3, 0), [0, 0, 128, 255]);

    // The other order: red covers blue entirely.
    let mut canvas = Canvas::new(4, 1, [0, 0, 0, 255]);
    canvas.draw_layer(
        &half_blue,
        &Field::zeros(3, 1),
        &Grid::new(3, 1),
        [1.0, 0.0],
    );
    canvas.draw_layer(&red, &Field::zeros(3, 1), &Grid::new(3, 1), [0.0, 0.0]);
    let out = canvas.to_rgba8();
    assert_eq!(out.pixel(1, 0), [255, 0, 0, 255]);
    assert_eq!(out.pixel(3, 0), [0, 0, 128, 255]);
}

#[test]
fn inactive_visible_pixels_are_drawn_as_isolated_squares() {
    // A continuity matte that excludes a visible column must not hide it at rest.
    let (w, h) = (9, 5);
    let image = opaque_noise(w, h, 5);
    let mut matte = vec![1u8; w * h];
    for y in 0..h {
        matte[y * w + 4] = 0;
    }
    let grid = Grid::from_matte(w, h, &matte);
    assert_eq!(try_warp_image(&image, &Field::zeros(w, h), &grid).unwrap(), image);
}

#[test]
fn output_does_not_depend_on_the_number_of_threads() {
    let (w, h) = (70, 53);
    let image = opaque_noise(w, h, 9);
    let field = field_from(w, h, |x, y| {
        [
            4.0 * (y / 7.0).sin() - 0.03 * x,
            3.0 * (x / 9.0).cos() + 0.02 * y,
        ]
    });
    let mut grid = Grid::new(w, h);
    for y in 10..40 {
        grid.link_right[y * w + 30] = false;
    }
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut canvas = Canvas::new(w + 6, h + 6, [10, 20, 30, 255]);
            canvas.draw_layer(&image, &field, &grid, [3.0, 3.0]);
            canvas
        })
    };
    let one = run(1);
    let three = run(3);
    assert!(one
        .data
        .iter()
        .zip(&three.data)
        .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)));
}

#[test]
fn non_finite_displacements_drop_their_pixels() {
    let image = opaque_noise(5, 5, 1);
    let mut field = Field::zeros(5, 5);
    field.dx[12] = f32::NAN;
    field.dy[3] = f32::INFINITY;
    let out = try_warp_image(&image, &field, &Grid::new(5, 5)).unwrap();
    assert_eq!(out.pixel(2, 2)[3], 0);
    assert_eq!(out.pixel(3, 0)[3], 0);
    assert_eq!(out.pixel(0, 0), image.pixel(0, 0));
}

#[test]
fn size_mismatches_are_errors_that_name_the_part() {
    let image = solid(4, 3, [1, 2, 3, 255]);
    let err = try_warp_image(&image, &Field::zeros(3, 3), &Grid::new(4, 3)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "The displacement field is 3×3, but the layer image is 4×3; the image, its displacement \
         field and its grid must be the same size."
    );
    let err = try_warp_image(&image, &Field::zeros(4, 3), &Grid::new(4, 4)).unwrap_err();
    assert!(err.to_string().starts_with("The grid is 4×4"));
    let err = RgbaImage::from_raw(2, 2, vec![0; 15]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "The RGBA data holds 15 bytes, but a 2×2 RGBA image needs 16 (4 bytes per pixel, row-major)."
    );
}

#[test]
fn empty_layers_and_canvases_draw_nothing() {
    let empty = RgbaImage::new(0, 0);
    let mut canvas = Canvas::new(3, 3, [9, 9, 9, 255]);
    canvas.draw_layer(&empty, &Field::zeros(0, 0), &Grid::new(0, 0), [0.0, 0.0]);
    assert_eq!(canvas.to_rgba8(), solid(3, 3, [9, 9, 9, 255]));
    let image = solid(2, 2, [1, 2, 3, 255]);
    let mut nothing = Canvas::new(0, 0, [0; 4]);
    nothing.draw_layer(&image, &Field::zeros(2, 2), &Grid::new(2, 2), [0.0, 0.0]);
}

#[test]
fn premultiply_round_trips_every_value() {
    for a in 1..=255u8 {
        for c in 0..=255u8 {
            assert_eq!(
                unpremultiply(premultiply([c, 255 - c, c / 2, a])),
                [c, 255 - c, c / 2, a]
            );
        }
    }
    assert_eq!(unpremultiply(premultiply([10, 20, 30, 0])), [0, 0, 0, 0]);
}

/// The banded frame (`draw_frame`) against the whole-frame canvas, with a warp that carries
/// pixels across band edges (a vertical swirl of ±20 px, a fold, holes, a second layer
/// half transparent), whole and cut into parts at rows that are not band edges.
#[test]
fn banded_frame_equals_the_whole_canvas_across_band_edges() {
    let (cw, ch) = (150, 130);
    let (w1, h1) = (120, 100);
    let back = opaque_noise(w1, h1, 7);
    // A swirl: rows move up and down by up to 20 px, more in the middle; a fold where
    // the columns 60..70 are pushed past their neighbours.
    let swirl = field_from(w1, h1, |x, y| {
        let fold = if (60.0..70.0).contains(&x) { 14.0 } else { 0.0 };
        [
            fold + 6.0 * (y / 13.0).sin(),
            20.0 * (x / 19.0).sin() * (1.0 - (y - 50.0).abs() / 60.0),
        ]
    });
    let mut front = RgbaImage::from_raw(70, 90, noise(11, 70 * 90 * 4)).unwrap();
    for (i, p) in front.data.chunks_exact_mut(4).enumerate() {
        // Holes (alpha 0) in a checker of 9-pixel squares, the rest half transparent.
        let (x, y) = (i % 70, i / 70);
        p[3] = if (x / 9 + y / 9) % 3 == 0 {
            0
        } else {
            100 + p[3] / 3
        };
    }
    let front_grid = alpha_matte(&front);
    let shear = field_from(70, 90, |x, y| [0.1 * y, -25.0 + 0.6 * x]);
    let background = [10, 20, 30, 200];
    let (back_grid, offsets) = (Grid::new(w1, h1), [[12.5, 9.0], [40.0, 33.25]]);

    let mut canvas = Canvas::new(cw, ch, background);
    canvas.draw_layer(&back, &swirl, &back_grid, offsets[0]);
    canvas.draw_layer(&front, &shear, &front_grid, offsets[1]);
    let whole = canvas.to_rgba8().data;

    let layers = [
        PreparedLayer::new(&back, swirl.clone(), &back_grid, offsets[0]).unwrap(),
        PreparedLayer::new(&front, shear.clone(), &front_grid, offsets[1]).unwrap(),
    ];
    for cuts in [
        vec![0, ch],
        vec![0, 45, ch],
        vec![0, 1, 31, 33, 64, 97, 129, ch],
    ] {
        let mut out = Vec::new();
        for part in cuts.windows(2) {
            let mut rows = vec![0u8; 4 * cw * (part[1] - part[0])];
            draw_frame(cw, ch, background, &layers, part[0]..part[1], &mut rows).unwrap();
            out.extend_from_slice(&rows);
        }
        assert!(
            out == whole,
            "cut at {cuts:?}: the banded frame differs from the canvas"
        );
    }
    // The warp does cross band edges: the frame differs from the picture left in place.
    let still = [PreparedLayer::new(&back, Field::zeros(w1, h1), &back_grid, offsets[0]).unwrap()];
    let mut rest = vec![0u8; 4 * cw * ch];
    draw_frame(cw, ch, background, &still, 0..ch, &mut rest).unwrap();
    assert_ne!(rest, whole);
}

#[test]
fn draw_frame_names_the_rows_and_the_buffer_it_needs() {
    let image = solid(2, 2, [1, 2, 3, 255]);
    let grid = Grid::new(2, 2);
    let layers = [PreparedLayer::new(&image, Field::zeros(2, 2), &grid, [0.0, 0.0]).unwrap()];
    let e = draw_frame(2, 2, [0; 4], &layers, 1..3, &mut [0; 16]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "Rows 1..3 are not rows of a frame 2 pixels high."
    );
    let e = draw_frame(2, 2, [0; 4], &layers, 0..2, &mut [0; 15]).unwrap_err();
    assert!(
        e.to_string().contains("holds 15 bytes") && e.to_string().contains("need 16"),
        "{e}"
    );
    let wrong = PreparedLayer::new(&image, Field::zeros(3, 2), &grid, [0.0, 0.0]).unwrap_err();
    assert!(matches!(wrong, RenderError::SizeMismatch { .. }));
}

// ---------------------------------------------------------------- views

type ViewScene = Vec<(RgbaImage, Field, Grid, [f64; 2])>;

/// Two layers (a warped picture with a cut, a half-transparent one with holes, offsets)
/// for the view tests.
fn view_scene() -> (
    ViewScene,
    usize,
    usize,
    [u8; 4],
) {
    let (cw, ch) = (170, 140);
    let (w1, h1) = (160, 128);
    // A picture with structure at every scale a view keeps (gradients, stripes of 12 px,
    // rings) and a little fine texture.
    let mut back = RgbaImage::new(w1, h1);
    let fine = noise(5, w1 * h1);
    for y in 0..h1 {
        for x in 0..w1 {
            let (xf, yf) = (x as f64, y as f64);
            let r = ((xf - 70.0).hypot(yf - 60.0) / 5.0).sin();
            let i = 4 * (y * w1 + x);
            back.data[i] = (128.0 + 100.0 * (xf / 12.0).sin()) as u8;
            back.data[i + 1] = (128.0 + 100.0 * r) as u8;
            back.data[i + 2] = ((255 * y / h1) as u8).wrapping_add(fine[y * w1 + x] / 16);
            back.data[i + 3] = 255;
        }
    }
    let swirl = field_from(w1, h1, |x, y| {
        [
            6.0 * (y / 23.0).sin() + 3.0,
            9.0 * (x / 31.0).sin() * (1.0 - (y - 64.0).abs() / 80.0),
        ]
    });
    let mut back_grid = Grid::new(w1, h1);
    back_grid.add_cut(&[[40.3, 30.2], [41.1, 90.7]]);
    let mut front = RgbaImage::from_raw(60, 50, noise(11, 60 * 50 * 4)).unwrap();
    for (i, p) in front.data.chunks_exact_mut(4).enumerate() {
        let (x, y) = (i % 60, i / 60);
        p[3] = if (x / 10 + y / 10) % 3 == 0 { 0 } else { 180 };
    }
    let front_grid = alpha_matte(&front);
    let shear = field_from(60, 50, |x, y| [0.1 * y, -5.0 + 0.2 * x]);
    let layers = vec![
        (back, swirl, back_grid, [4.5, 6.0]),
        (front, shear, front_grid, [90.0, 70.25]),
    ];
    (layers, cw, ch, [10, 20, 30, 255])
}

/// The whole frame of the view scene's layers, drawn by `draw_frame`.
fn whole_frame(layers: &ViewScene, cw: usize, ch: usize, background: [u8; 4]) -> Vec<u8> {
    let prepared: Vec<_> = layers
        .iter()
        .map(|(i, f, g, o)| PreparedLayer::new(i, f.clone(), g, *o).unwrap())
        .collect();
    let mut whole = vec![0u8; 4 * cw * ch];
    draw_frame(cw, ch, background, &prepared, 0..ch, &mut whole).unwrap();
    whole
}

/// The view scene's layers as `draw_view` reads them.
fn view_layers(layers: &ViewScene) -> Vec<ViewLayer<'_>> {
    layers
        .iter()
        .map(|(image, field, grid, offset)| ViewLayer {
            image,
            field,
            grid,
            offset: *offset,
        })
        .collect()
}

#[test]
fn a_view_at_its_own_scale_is_the_region_of_the_frame_bit_for_bit() {
    let (layers, cw, ch, background) = view_scene();
    let whole = whole_frame(&layers, cw, ch, background);
    let views = view_layers(&layers);
    for region in [
        [0, 0, cw, ch],
        [17, 33, 101, 97],
        [0, 64, cw, 65],
        [169, 0, 170, 140],
    ] {
        let [x0, y0, x1, y1] = region;
        let mut out = vec![0u8; 4 * (x1 - x0) * (y1 - y0)];
        draw_view(cw, ch, background, &views, 1, region, &mut out).unwrap();
        let mut want = Vec::new();
        for y in y0..y1 {
            want.extend_from_slice(&whole[4 * (y * cw + x0)..4 * (y * cw + x1)]);
        }
        assert!(out == want, "region {region:?} differs from the frame's");
    }
    let e = draw_view(
        cw,
        ch,
        background,
        &views,
        4,
        [0, 0, 44, 10],
        &mut [0; 4 * 44 * 10],
    )
    .unwrap_err();
    assert!(e.to_string().contains("43×35"), "{e}");
}

/// The frame box-filtered by `k` (each block's premultiplied mean), as the canvas shows a
/// full frame scaled down.
fn box_down(data: &[u8], w: usize, h: usize, k: usize) -> Vec<u8> {
    let (lw, lh) = view_size(w, h, k);
    let mut out = vec![0u8; 4 * lw * lh];
    for j in 0..lh {
        for i in 0..lw {
            let mut acc = [0f32; 4];
            let mut n = 0.0;
            for y in j * k..((j + 1) * k).min(h) {
                for x in i * k..((i + 1) * k).min(w) {
                    let p = premultiply(
                        data[4 * (y * w + x)..4 * (y * w + x) + 4]
                            .try_into()
                            .unwrap(),
                    );
                    for c in 0..4 {
                        acc[c] += p[c];
                    }
                    n += 1.0;
                }
            }
            let px = unpremultiply(acc.map(|v| v / n));
            out[4 * (j * lw + i)..4 * (j * lw + i) + 4].copy_from_slice(&px);
        }
    }
    out
}

/// A view drawn 2, 3 and 4 times smaller looks like the full frame box-filtered by the
/// same factor: the mean and the 99th percentile of the channel differences stay small
/// (what differs: the edges of the cut, the holes and the layer's border, within a pixel
/// of the smaller frame).
#[test]
fn a_smaller_view_matches_the_full_frame_scaled_down() {
    let (layers, cw, ch, background) = view_scene();
    let whole = whole_frame(&layers, cw, ch, background);
    let views = view_layers(&layers);
    for k in [2, 3, 4] {
        let (vw, vh) = view_size(cw, ch, k);
        let mut out = vec![0u8; 4 * vw * vh];
        draw_view(cw, ch, background, &views, k, [0, 0, vw, vh], &mut out).unwrap();
        let want = box_down(&whole, cw, ch, k);
        let mut d: Vec<u8> = out.iter().zip(&want).map(|(a, b)| a.abs_diff(*b)).collect();
        d.sort_unstable();
        let mean = d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        let p99 = d[d.len() * 99 / 100];
        eprintln!(
            "view 1/{k}: mean difference {mean:.2}, 99th percentile {p99}, max {}",
            d[d.len() - 1]
        );
        assert!(
            mean < 4.0 && p99 < 40,
            "view 1/{k}: mean {mean:.2}, 99th percentile {p99}"
        );
        // A region of it is the same region of the whole view.
        let mut part = vec![0u8; 4 * 10 * 7];
        draw_view(cw, ch, background, &views, k, [3, 5, 13, 12], &mut part).unwrap();
        for (r, row) in part.chunks_exact(40).enumerate() {
            assert_eq!(row, &out[4 * ((5 + r) * vw + 3)..4 * ((5 + r) * vw + 13)]);
        }
    }
}
