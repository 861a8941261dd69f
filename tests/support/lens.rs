//! A real lens for the video tests: a ROS `camera_info` calibration (axis off the image's
//! centre, barrel distortion) and an ideal pinhole image warped through it, as that lens
//! would have taken it. The warp runs the other way from skein's correction: every raw
//! pixel is undistorted by `opencv-ros-camera`'s iterative `undistort` and sampled from
//! the ideal image; skein's rectifier distorts ideal rays forward.

use cam_geom::Pixels;
use nalgebra::{Dyn, OMatrix, U2};
use opencv_ros_camera::from_ros_yaml;

/// The lens: principal point 25 px right of and 20 px above the centre of a 640x480
/// image, k1 -0.35, k2 0.12, p1 0.001, p2 -0.0008, with focal length `focal_px`.
pub fn camera_info_yaml(focal_px: f64) -> String {
    let (cx, cy) = (345.0, 220.0);
    format!(
        "image_width: 640\nimage_height: 480\ncamera_name: test_lens\n\
         camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{f}, 0.0, {cx}, 0.0, {f}, {cy}, 0.0, 0.0, 1.0]\n\
         distortion_model: plumb_bob\n\
         distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.35, 0.12, 0.001, -0.0008, 0.0]\n\
         rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{f}, 0.0, {cx}, 0.0, 0.0, {f}, {cy}, 0.0, 0.0, 0.0, 1.0, 0.0]\n",
        f = focal_px
    )
}

/// `ideal` (RGB, `w`×`h`, a pinhole image with focal length `focal_px` and its principal
/// point at the centre) as the lens of `camera_info` (same size) would have taken it.
pub fn warp_through(camera_info: &str, ideal: &[u8], w: usize, h: usize, focal_px: f64) -> Vec<u8> {
    let lens = from_ros_yaml::<f64, _>(camera_info.as_bytes())
        .expect("the test's camera_info")
        .intrinsics;
    let (fx, fy, cx, cy) = (
        lens.p[(0, 0)],
        lens.p[(1, 1)],
        lens.p[(0, 2)],
        lens.p[(1, 2)],
    );
    let n = w * h;
    let raw = OMatrix::<f64, Dyn, U2>::from_iterator(
        n,
        (0..n)
            .map(|i| (i % w) as f64)
            .chain((0..n).map(|i| (i / w) as f64)),
    );
    let undistorted = lens.undistort(&Pixels { data: raw });
    let mut out = vec![0u8; n * 3];
    for i in 0..n {
        // The ray of this raw pixel, in the ideal image.
        let x = (undistorted.data[(i, 0)] - cx) / fx * focal_px + w as f64 / 2.0;
        let y = (undistorted.data[(i, 1)] - cy) / fy * focal_px + h as f64 / 2.0;
        if x < 0.0 || y < 0.0 || x > (w - 1) as f64 || y > (h - 1) as f64 {
            continue;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (ax, ay) = (x - x0 as f64, y - y0 as f64);
        for ch in 0..3 {
            let at = |xx: usize, yy: usize| f64::from(ideal[(yy * w + xx) * 3 + ch]);
            let top = at(x0, y0) * (1.0 - ax) + at(x1, y0) * ax;
            let bottom = at(x0, y1) * (1.0 - ax) + at(x1, y1) * ax;
            out[i * 3 + ch] = (top * (1.0 - ay) + bottom * ay).round() as u8;
        }
    }
    out
}

/// `rgb` (`w`×`h`) as a binary PPM (P6) file, which ffmpeg reads as an image.
pub fn ppm(rgb: &[u8], w: usize, h: usize) -> Vec<u8> {
    let mut out = format!("P6\n{w} {h}\n255\n").into_bytes();
    out.extend_from_slice(rgb);
    out
}
