//! Image references: `data:` URIs decoded here, other references read by the front end
//! (the core never opens files), PNG/JPEG decoded from bytes.

use base64::Engine as _;

use crate::render::RgbaImage;

/// Whether `reference` is a `data:` URI rather than a path.
pub fn is_data_uri(reference: &str) -> bool {
    // Bytes, not a str slice: a name such as `日本.png` has no char boundary at 5.
    reference.as_bytes().get(..5).is_some_and(|head| head.eq_ignore_ascii_case(b"data:"))
}

/// The bytes of a base64 `data:` URI (`data:image/png;base64,...`).
pub fn data_uri_bytes(uri: &str) -> Result<Vec<u8>, String> {
    let rest = &uri[5..];
    let comma = rest.find(',').ok_or("this data: URI has no comma before its data; write data:image/png;base64,<data>")?;
    let (header, payload) = (&rest[..comma], &rest[comma + 1..]);
    if !header.split(';').any(|part| part.eq_ignore_ascii_case("base64")) {
        return Err("only base64 data: URIs are supported; write data:image/png;base64,<data>".to_string());
    }
    let cleaned: String = payload.chars().filter(|c| !c.is_ascii_whitespace()).collect();
    base64::engine::general_purpose::STANDARD
        .decode(cleaned.as_bytes())
        .or_else(|_| base64::engine::general_purpose::STANDARD_NO_PAD.decode(cleaned.trim_end_matches('=')))
        .map_err(|e| format!("the data: URI is not valid base64 ({e})"))
}

/// Decodes a PNG or JPEG into straight-alpha RGBA8, upright by its EXIF orientation.
pub fn decode_image(bytes: &[u8]) -> Result<RgbaImage, String> {
    if bytes.starts_with(b"8BPS") { return Err("a Photoshop PSD, not a PNG or JPEG image; save it, or each of its layers, as PNG".into()) }
    let format = image::guess_format(bytes)
        .map_err(|_| "not a PNG or JPEG image (unrecognised file contents); save it as PNG or JPEG")?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(format!("a {format:?} image; inkwarp reads PNG and JPEG, save it as one of those"));
    }
    let damaged = |e: image::ImageError| format!("the {format:?} image could not be decoded ({e}): the file is damaged or cut short; save it again");
    let mut decoder = image::ImageReader::with_format(std::io::Cursor::new(bytes), format).into_decoder().map_err(damaged)?;
    // The header's size first: a few kilobytes can declare a picture that needs gigabytes.
    let (width, height) = image::ImageDecoder::dimensions(&decoder);
    crate::limits::check_size("the picture", width as usize, height as usize)?;
    let orientation = image::ImageDecoder::orientation(&mut decoder).unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut decoded = image::DynamicImage::from_decoder(decoder).map_err(damaged)?;
    decoded.apply_orientation(orientation);
    let mut rgba = decoded.to_rgba8();
    if decoded.color().bits_per_pixel() == 16 * decoded.color().channel_count() as u16 {
        // Sixteen bits rounded to eight, but never a faint nonzero value (a matte's, an alpha's) to 0.
        rgba.iter_mut().zip(decoded.to_rgba16().iter()).for_each(|(n, &w)| *n = (*n).max((w > 0) as u8));
    }
    Ok(RgbaImage { width: rgba.width() as usize, height: rgba.height() as usize, data: rgba.into_raw() })
}

/// A matte from an image: grey level times alpha, so black or transparent pixels are 0, and
/// only they (a faint pixel rounds to 1, not 0: nonzero is connected).
pub fn matte_values(image: &RgbaImage) -> Vec<u8> {
    let value = |px: &[u8]| {
        // Rec. 601 luma, then scaled by alpha; exact for pure black/white and grey.
        let luma = (299 * px[0] as u32 + 587 * px[1] as u32 + 114 * px[2] as u32 + 500) / 1000;
        (((luma * px[3] as u32 + 127) / 255) as u8).max((px[3] > 0 && px[..3] != [0, 0, 0]) as u8)
    };
    image.data.chunks_exact(4).map(value).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(width: u32, height: u32, pixels: &[u8]) -> Vec<u8> {
        let mut bytes = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut bytes),
            pixels,
            width,
            height,
            image::ExtendedColorType::Rgba8,
        )
        .unwrap();
        bytes
    }

    #[test]
    fn decodes_a_png_data_uri_exactly() {
        let pixels: Vec<u8> = (0..2 * 3 * 4).map(|i| (i * 10) as u8).collect();
        let encoded = base64::engine::general_purpose::STANDARD.encode(png(2, 3, &pixels));
        let uri = format!("data:image/png;base64,{encoded}");
        assert!(is_data_uri(&uri));
        let image = decode_image(&data_uri_bytes(&uri).unwrap()).unwrap();
        assert_eq!((image.width, image.height), (2, 3));
        assert_eq!(image.data, pixels);
    }

    #[test]
    fn rejects_what_is_not_an_image() {
        assert!(decode_image(b"hello")
            .unwrap_err()
            .contains("not a PNG or JPEG"));
        assert!(data_uri_bytes("data:image/png,abc")
            .unwrap_err()
            .contains("base64"));
        assert!(data_uri_bytes("data:image/png;base64,@@@")
            .unwrap_err()
            .contains("not valid base64"));
    }

    #[test]
    fn non_ascii_names_are_paths_not_uris() {
        for name in ["日本.png", "фото.png", "größe.png", "d", "data", "DATA:x", "é"] {
            assert_eq!(is_data_uri(name), name.eq_ignore_ascii_case("DATA:x"), "{name}");
        }
    }

    #[test]
    fn a_huge_declared_size_is_refused_before_decoding() {
        // A valid PNG header declaring 40000×40000, with almost no data behind it.
        let mut bytes = png(1, 1, &[0, 0, 0, 255]);
        bytes[16..20].copy_from_slice(&40_000u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&40_000u32.to_be_bytes());
        let crc = crc32(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
        let err = decode_image(&bytes).unwrap_err();
        assert!(err.contains("40000×40000") && err.contains("at most"), "{err}");
    }

    #[test]
    fn a_jpeg_is_turned_upright_by_its_exif_orientation() {
        // 6 wide, 4 high, red on its left half; tagged "rotate 90° clockwise to view", as a
        // phone held upright stores its photograph, and as viewers, browsers and drawing
        // programs show it (a drawing traced there lines up only with the upright picture).
        let pixels: Vec<u8> = (0..4 * 6).flat_map(|i| if i % 6 < 3 { [255, 0, 0] } else { [0, 0, 255] }).collect();
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100).encode(&pixels, 6, 4, image::ExtendedColorType::Rgb8).unwrap();
        let mut exif = b"Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01\0\x06\0\0\0\0\0\0".to_vec();
        let mut app1 = vec![0xff, 0xe1];
        app1.extend_from_slice(&((exif.len() + 2) as u16).to_be_bytes());
        app1.append(&mut exif);
        jpeg.splice(2..2, app1);
        let upright = decode_image(&jpeg).unwrap();
        assert_eq!((upright.width, upright.height), (4, 6));
        let px = |x: usize, y: usize| &upright.data[4 * (y * 4 + x)..4 * (y * 4 + x) + 3];
        // The left half turned clockwise is the top half.
        assert!(px(1, 0)[0] > 200 && px(1, 0)[2] < 60, "{:?}", px(1, 0));
        assert!(px(1, 5)[2] > 200 && px(1, 5)[0] < 60, "{:?}", px(1, 5));
    }

    fn crc32(data: &[u8]) -> u32 {
        let mut crc = 0xffff_ffffu32;
        for &b in data {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xedb8_8320 } else { crc >> 1 };
            }
        }
        !crc
    }

    #[test]
    fn matte_is_grey_times_alpha() {
        let image = RgbaImage {
            width: 3,
            height: 1,
            data: vec![255, 255, 255, 255, 0, 0, 0, 255, 255, 255, 255, 0],
        };
        assert_eq!(matte_values(&image), vec![255, 0, 0]);
        // Faint is not a hole: dark grey at low alpha, and a pure blue (luma 0), are 1.
        let faint = RgbaImage { width: 2, height: 1, data: vec![3, 3, 3, 20, 0, 0, 1, 255] };
        assert_eq!(matte_values(&faint), vec![1, 1]);
    }

    #[test]
    fn a_faint_sixteen_bit_value_stays_nonzero() {
        // 16-bit grey with alpha: 1, 128 and 129 of 65535 round to 0, 0 and 1 in 8 bits; a
        // matte or alpha that faint must stay connected (nonzero), and 0 stay 0.
        let mut bytes = Vec::new();
        let pixels: Vec<u8> = [[0u16, 65535], [1, 1], [128, 128], [129, 65535]].iter().flatten().flat_map(|v| v.to_ne_bytes()).collect();
        image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(&mut bytes), &pixels, 4, 1, image::ExtendedColorType::La16).unwrap();
        let image = decode_image(&bytes).unwrap();
        let alpha: Vec<u8> = image.data.chunks(4).map(|p| p[3]).collect();
        assert_eq!((alpha, image.data[0], image.data[4], image.data[8]), (vec![255, 1, 1, 255], 0, 1, 1));
        assert_eq!(matte_values(&image), vec![0, 1, 1, 1]);
    }
}
