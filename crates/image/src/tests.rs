use super::*;

#[test]
fn strided_view_reads_the_callers_rows_in_place() {
    // 3x2 pixels in rows 5 apart; the padding must never be read.
    let data: Vec<u16> = vec![1, 2, 3, 99, 99, 4, 5, 6];
    let view = ImageRef::with_stride(&data, 3, 2, 5).unwrap();
    assert_eq!(view.row(1), &[4, 5, 6]);
    assert_eq!(view.get(2, 0), 3);
    assert!(std::ptr::eq(view.row(0).as_ptr(), data.as_ptr()), "borrowed, not copied");
    assert_eq!(view.as_contiguous_slice(), None);
    assert_eq!(view.to_image().as_slice(), &[1, 2, 3, 4, 5, 6]);
}

#[test]
fn views_reject_buffers_that_do_not_hold_the_image() {
    let data = [0u8; 10];
    assert_eq!(ImageRef::new(&data, 4, 3).unwrap_err(), Error::BufferSize { width: 4, height: 3, len: 10 });
    assert_eq!(ImageRef::with_stride(&data, 4, 3, 3).unwrap_err(), Error::Stride { width: 4, stride: 3 });
    assert!(matches!(ImageRef::with_stride(&data, 4, 3, 4), Err(Error::StridedBufferSize { .. })));
    // The last row needs only `width` pixels, not a whole stride.
    assert!(ImageRef::with_stride(&data, 2, 3, 4).is_ok());
    assert!(matches!(
        ImageRef::<[u8; 3]>::from_interleaved(&data, 1, 1, 4),
        Err(Error::Interleave { channels: 3, stride: 4 })
    ));
}

#[test]
fn grey_conversion_is_rec601_on_the_16_bit_scale() {
    let rgb: [u8; 6] = [255, 255, 255, 255, 0, 0];
    let view = ImageRef::<[u8; 3]>::from_interleaved(&rgb, 2, 1, 6).unwrap();
    let grey = view.to_gray16();
    assert_eq!(grey.as_slice(), &[65535, ((299u32 * 65535 + 500) / 1000) as u16]);
    let grey8 = ImageRef::new(&[0u8, 1, 255][..], 3, 1).unwrap().to_gray16();
    assert_eq!(grey8.as_slice(), &[0, 257, 65535]);
    let rgba16 = [[1000u16, 2000, 3000, 7]];
    assert_eq!(ImageRef::new(&rgba16[..], 1, 1).unwrap().to_gray16().get(0, 0), luma16(1000, 2000, 3000));
}

#[test]
fn owned_images_view_as_themselves() {
    let image = Image::from_fn(3, 2, |x, y| (x + 10 * y) as f32);
    let view = image.view();
    assert_eq!(view.size(), (3, 2));
    assert_eq!(view.as_contiguous_slice(), Some(image.as_slice()));
    assert_eq!(view.to_image(), image);
}

#[test]
fn disparity_range_default_and_count() {
    assert_eq!(DisparityRange::new(5, 5).unwrap_err(), Error::EmptyRange { min: 5, max: 5 });
    assert_eq!(DisparityRange::new(-8, 8).unwrap().count(), 16);
    assert_eq!(DisparityRange::default_for_width(450).max, 128);
    assert_eq!(DisparityRange::default_for_width(10).max, 10);
}
