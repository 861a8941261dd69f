//! Lens correction for a calibrated camera: a real lens bends straight lines (barrel or
//! pincushion distortion) and its optical axis rarely pierces the image's centre, while
//! the detector turns pixels into bearings with an ideal pinhole centred in the image
//! (`FrameMeta::focal_px`). A [`Rectifier`] resamples each decoded frame into that ideal
//! camera, as ROS's `image_proc` rectifies an `image_raw`, so everything downstream
//! (the dashboard, the detector, recordings) sees a pinhole image.
//!
//! The calibration is the ROS/OpenCV `camera_info` YAML that ROS's `camera_calibration`
//! (`cameracalibrator.py`) and `camera_info_manager` write: `image_width`,
//! `image_height`, `camera_matrix` (K), `distortion_model` (`plumb_bob`: k1, k2, p1, p2,
//! k3), `distortion_coefficients`, `rectification_matrix`, `projection_matrix` (P). It is
//! read, and its distortion modelled, by the `opencv-ros-camera` crate.
//!
//! The ideal camera: `P`'s focal length (scaled to the output width), principal point at
//! the output's centre (`width_px / 2`, `height_px / 2`, the detector's convention), no
//! distortion. Each output pixel's ray is distorted by the calibration into the decoded
//! frame (scaled from the calibrated size to the stream's when they differ by a factor,
//! e.g. a camera calibrated at 1920x1080 streaming 1280x720) and sampled bilinearly;
//! rays that land outside the decoded frame are black. The lookup table is made once per
//! (stream size, output size), exactly on a grid every 8 pixels and interpolated between.

use crate::scale::RgbFrame;
use nalgebra::{Dyn, OMatrix, U2};
use opencv_ros_camera::{
    NamedIntrinsicParameters, RosCameraInfo, RosOpenCvIntrinsics, UndistortedPixels,
};
use std::path::Path;

/// A camera's calibration, from its `camera_info` YAML.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// `camera_name`.
    pub name: String,
    /// The size the camera was calibrated at, pixels.
    pub width_px: u32,
    /// The size the camera was calibrated at, pixels.
    pub height_px: u32,
    intrinsics: RosOpenCvIntrinsics<f64>,
}

impl Calibration {
    /// Reads a ROS/OpenCV `camera_info` YAML file.
    ///
    /// # Errors
    /// The file cannot be read, is no `camera_info` YAML (the parser's message), has a
    /// distortion model other than `plumb_bob`, a matrix of the wrong size, or a zero
    /// image size or focal length; each message names the file.
    pub fn from_ros_yaml_file(path: &Path) -> Result<Calibration, String> {
        let file = std::fs::File::open(path)
            .map_err(|e| format!("camera_info_file {}: {e}", path.display()))?;
        Calibration::from_ros_yaml(file)
            .map_err(|e| format!("camera_info_file {}: {e}", path.display()))
    }

    /// Reads a ROS/OpenCV `camera_info` YAML document from `reader`.
    ///
    /// # Errors
    /// As [`Calibration::from_ros_yaml_file`], without the file's name.
    pub fn from_ros_yaml(reader: impl std::io::Read) -> Result<Calibration, String> {
        // Parsed here rather than by `opencv_ros_camera::from_ros_yaml`, whose error does
        // not say where the YAML is wrong; serde_yaml's names the field and the line.
        let info: RosCameraInfo<f64> =
            serde_yaml::from_reader(reader).map_err(|e| e.to_string())?;
        let NamedIntrinsicParameters {
            name,
            width,
            height,
            intrinsics,
        } = NamedIntrinsicParameters::try_from(info).map_err(|e| match e {
            opencv_ros_camera::Error::UnknownDistortionModel => {
                "distortion_model: only plumb_bob (k1, k2, p1, p2, k3) is supported".to_string()
            }
            opencv_ros_camera::Error::BadMatrixSize => "camera_matrix (3x3), \
                distortion_coefficients (1x5), rectification_matrix (3x3), projection_matrix \
                (3x4): a matrix of another size"
                .to_string(),
            e => format!("rectification_matrix: {e} (it cannot be inverted)"),
        })?;
        let calibration = Calibration {
            name,
            width_px: u32::try_from(width).map_err(|_| format!("image_width: {width}"))?,
            height_px: u32::try_from(height).map_err(|_| format!("image_height: {height}"))?,
            intrinsics,
        };
        if calibration.width_px == 0 || calibration.height_px == 0 {
            return Err(format!(
                "image_width, image_height: {}x{} is no image size",
                calibration.width_px, calibration.height_px
            ));
        }
        let (fx, fy) = (calibration.focal_px(), calibration.intrinsics.p[(1, 1)]);
        if !(fx.is_finite() && fx > 0.0 && fy.is_finite() && fy > 0.0) {
            return Err(format!(
                "projection_matrix: focal lengths {fx} and {fy} px, expected positive ones"
            ));
        }
        Ok(calibration)
    }

    /// The rectified camera's focal length at the calibrated width (`P`'s fx), pixels.
    pub fn focal_px(&self) -> f64 {
        self.intrinsics.p[(0, 0)]
    }

    /// The rectified camera's horizontal field of view, degrees.
    pub fn horizontal_fov_deg(&self) -> f64 {
        2.0 * (f64::from(self.width_px) / 2.0 / self.focal_px())
            .atan()
            .to_degrees()
    }

    /// Where the ideal camera's pixels (`points`: `(x, y)`, pixels of an image
    /// `out_w`×`out_h` whose focal length is [`Calibration::focal_px`] scaled to `out_w`,
    /// principal point at its centre) fall in the raw image at the calibrated size.
    pub fn distort(&self, points: &[(f64, f64)], out_w: u32, out_h: u32) -> Vec<(f64, f64)> {
        let p = &self.intrinsics.p;
        let f_out = self.focal_px() * f64::from(out_w) / f64::from(self.width_px);
        let (fx, fy, cx, cy) = (p[(0, 0)], p[(1, 1)], p[(0, 2)], p[(1, 2)]);
        let undistorted = OMatrix::<f64, Dyn, U2>::from_iterator(
            points.len(),
            // Column-major: every x, then every y.
            points
                .iter()
                .map(|&(u, _)| fx * (u - f64::from(out_w) / 2.0) / f_out + cx)
                .chain(
                    points
                        .iter()
                        .map(|&(_, v)| fy * (v - f64::from(out_h) / 2.0) / f_out + cy),
                ),
        );
        let distorted = self
            .intrinsics
            .distort(&UndistortedPixels { data: undistorted });
        (0..points.len())
            .map(|i| (distorted.data[(i, 0)], distorted.data[(i, 1)]))
            .collect()
    }
}

/// Spacing of the grid on which the lens is computed exactly, output pixels.
const GRID_PX: u32 = 8;

/// For each output pixel, where to sample the decoded frame (`x`, `y` in its pixels);
/// `None` outside it.
#[derive(Debug)]
struct Table {
    input: (u32, u32),
    output: (u32, u32),
    source: Vec<Option<(f32, f32)>>,
}

/// Resamples decoded frames into the ideal pinhole camera of a [`Calibration`].
#[derive(Debug)]
pub struct Rectifier {
    calibration: Calibration,
    table: Option<Table>,
}

impl Rectifier {
    /// A rectifier for `calibration`.
    pub fn new(calibration: Calibration) -> Rectifier {
        Rectifier {
            calibration,
            table: None,
        }
    }

    /// The calibration.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// `frame` rectified into an ideal pinhole image `out_w`×`out_h` (see the module docs).
    ///
    /// # Errors
    /// The frame's aspect ratio is not the calibrated one (more than 1 % apart: the
    /// stream is not the calibrated camera's, or it is cropped), either size is empty, or
    /// the frame's buffer has the wrong length.
    pub fn rectify(
        &mut self,
        frame: &RgbFrame,
        out_w: u32,
        out_h: u32,
    ) -> Result<RgbFrame, String> {
        let (w, h) = (frame.width_px, frame.height_px);
        if w == 0 || h == 0 || out_w == 0 || out_h == 0 {
            return Err(format!("an empty frame ({w}x{h} to {out_w}x{out_h})"));
        }
        if frame.rgb.len() != w as usize * h as usize * 3 {
            return Err(format!("a {w}x{h} frame with the wrong number of bytes"));
        }
        let c = &self.calibration;
        let (sx, sy) = (
            f64::from(w) / f64::from(c.width_px),
            f64::from(h) / f64::from(c.height_px),
        );
        if (sx - sy).abs() > 0.01 * sx {
            return Err(format!(
                "camera_info_file: {} was calibrated at {}x{}, the stream is {w}x{h} (another \
                 aspect ratio: not that camera, or cropped)",
                c.name, c.width_px, c.height_px
            ));
        }
        if self
            .table
            .as_ref()
            .is_none_or(|t| t.input != (w, h) || t.output != (out_w, out_h))
        {
            // The lens is distorted exactly at the nodes of a grid every GRID_PX pixels
            // and interpolated between them (distortion is smooth): the table is made in
            // milliseconds, within a camera tick, at any size.
            let (nx, ny) = (out_w.div_ceil(GRID_PX) + 1, out_h.div_ceil(GRID_PX) + 1);
            let nodes: Vec<(f64, f64)> = (0..ny)
                .flat_map(|j| {
                    (0..nx).map(move |i| (f64::from(i * GRID_PX), f64::from(j * GRID_PX)))
                })
                .collect();
            let nodes = c.distort(&nodes, out_w, out_h);
            let node = |i: u32, j: u32| nodes[(j * nx + i) as usize];
            let g = f64::from(GRID_PX);
            let source = (0..out_h)
                .flat_map(|v| (0..out_w).map(move |u| (u, v)))
                .map(|(u, v)| {
                    let (i, j) = (u / GRID_PX, v / GRID_PX);
                    let (a, b) = (f64::from(u % GRID_PX) / g, f64::from(v % GRID_PX) / g);
                    let lerp = |p: (f64, f64), q: (f64, f64), t: f64| {
                        (p.0 + (q.0 - p.0) * t, p.1 + (q.1 - p.1) * t)
                    };
                    let top = lerp(node(i, j), node(i + 1, j), a);
                    let bottom = lerp(node(i, j + 1), node(i + 1, j + 1), a);
                    let (x, y) = lerp(top, bottom, b);
                    let (x, y) = (x * sx, y * sy);
                    (x >= 0.0 && y >= 0.0 && x <= f64::from(w - 1) && y <= f64::from(h - 1))
                        .then_some((x as f32, y as f32))
                })
                .collect();
            self.table = Some(Table {
                input: (w, h),
                output: (out_w, out_h),
                source,
            });
        }
        let table = self.table.as_ref().expect("made above");
        let mut rgb = vec![0u8; out_w as usize * out_h as usize * 3];
        let at =
            |x: usize, y: usize, ch: usize| f32::from(frame.rgb[(y * w as usize + x) * 3 + ch]);
        for (i, src) in table.source.iter().enumerate() {
            let Some((x, y)) = *src else { continue };
            let (x0, y0) = (x.floor() as usize, y.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w as usize - 1), (y0 + 1).min(h as usize - 1));
            let (fx, fy) = (x - x0 as f32, y - y0 as f32);
            for ch in 0..3 {
                let top = at(x0, y0, ch) * (1.0 - fx) + at(x1, y0, ch) * fx;
                let bottom = at(x0, y1, ch) * (1.0 - fx) + at(x1, y1, ch) * fx;
                rgb[i * 3 + ch] = (top * (1.0 - fy) + bottom * fy).round() as u8;
            }
        }
        Ok(RgbFrame {
            width_px: out_w,
            height_px: out_h,
            rgb,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 640x480 calibration with its axis off the centre and a barrel lens.
    const CAMERA_INFO: &str = "image_width: 640
image_height: 480
camera_name: gimbal
camera_matrix:
  rows: 3
  cols: 3
  data: [500.0, 0.0, 335.0, 0.0, 500.0, 230.0, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.25, 0.08, 0.001, -0.0005, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [500.0, 0.0, 335.0, 0.0, 0.0, 500.0, 230.0, 0.0, 0.0, 0.0, 1.0, 0.0]
";

    fn calibration() -> Calibration {
        Calibration::from_ros_yaml(CAMERA_INFO.as_bytes()).unwrap()
    }

    /// The centroid of the pixels brighter than 128 (red channel).
    fn bright_centroid(f: &RgbFrame) -> (f64, f64) {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for y in 0..f.height_px as usize {
            for x in 0..f.width_px as usize {
                let r = f64::from(f.rgb[(y * f.width_px as usize + x) * 3]);
                if r > 128.0 {
                    (sx, sy, n) = (sx + x as f64 * r, sy + y as f64 * r, n + r);
                }
            }
        }
        assert!(n > 0.0, "no bright pixel");
        (sx / n, sy / n)
    }

    #[test]
    fn reads_a_camera_info_file_and_names_what_is_wrong() {
        let c = calibration();
        assert_eq!(
            (c.name.as_str(), c.width_px, c.height_px),
            ("gimbal", 640, 480)
        );
        assert_eq!(c.focal_px(), 500.0);
        assert!(
            (c.horizontal_fov_deg() - 65.24).abs() < 0.01,
            "{}",
            c.horizontal_fov_deg()
        );
        let e =
            Calibration::from_ros_yaml(CAMERA_INFO.replace("plumb_bob", "equidistant").as_bytes())
                .unwrap_err();
        assert!(e.starts_with("distortion_model:"), "{e}");
        let e = Calibration::from_ros_yaml("image_width: 640\n".as_bytes()).unwrap_err();
        assert!(e.contains("image_height"), "{e}");
        let e = Calibration::from_ros_yaml(CAMERA_INFO.replace("cols: 5", "cols: 4").as_bytes())
            .unwrap_err();
        assert!(e.contains("distortion_coefficients (1x5)"), "{e}");
        let e = Calibration::from_ros_yaml_file(Path::new("/nonexistent/cam.yaml")).unwrap_err();
        assert!(
            e.starts_with("camera_info_file /nonexistent/cam.yaml:"),
            "{e}"
        );
        let e = Calibration::from_ros_yaml(
            CAMERA_INFO
                .replace(
                    "data: [500.0, 0.0, 335.0, 0.0, 0.0",
                    "data: [0.0, 0.0, 335.0, 0.0, 0.0",
                )
                .as_bytes(),
        )
        .unwrap_err();
        assert!(e.starts_with("projection_matrix:"), "{e}");
    }

    /// A bright spot drawn where the lens puts a ray comes out of the rectifier where the
    /// ideal pinhole puts that ray, at the calibrated size and at another size.
    #[test]
    fn a_point_lands_where_the_ideal_pinhole_puts_it() {
        let c = calibration();
        for (w, h, out_w, out_h) in [(640, 480, 640, 480), (1280, 960, 320, 240)] {
            let scale = f64::from(w) / 640.0;
            // A ray 14° right and 9° down of the axis: in the ideal output it is at
            // f·tan(angle) from the centre.
            let f_out = 500.0 * f64::from(out_w) / 640.0;
            let ideal = (
                f64::from(out_w) / 2.0 + f_out * 14f64.to_radians().tan(),
                f64::from(out_h) / 2.0 + f_out * 9f64.to_radians().tan(),
            );
            let raw = c.distort(&[ideal], out_w, out_h)[0];
            let raw = (raw.0 * scale, raw.1 * scale);
            // The raw frame: a bright disc of radius 4 px (scaled) around `raw`.
            let r = 4.0 * scale;
            let mut rgb = vec![0u8; (w * h * 3) as usize];
            for y in 0..h as usize {
                for x in 0..w as usize {
                    if (x as f64 - raw.0).hypot(y as f64 - raw.1) <= r {
                        rgb[(y * w as usize + x) * 3] = 255;
                    }
                }
            }
            let frame = RgbFrame {
                width_px: w,
                height_px: h,
                rgb,
            };
            let mut rectifier = Rectifier::new(c.clone());
            let out = rectifier.rectify(&frame, out_w, out_h).unwrap();
            let got = bright_centroid(&out);
            let off = (got.0 - ideal.0).hypot(got.1 - ideal.1);
            assert!(
                off < 0.5,
                "{w}x{h}→{out_w}x{out_h}: {got:?} vs {ideal:?} ({off:.2} px)"
            );
            // Without correction the spot is far from there: the lens matters here.
            let uncorrected = (
                raw.0 * f64::from(out_w) / f64::from(w),
                raw.1 * f64::from(out_w) / f64::from(w),
            );
            assert!((uncorrected.0 - ideal.0).hypot(uncorrected.1 - ideal.1) > 3.0);
        }
    }

    #[test]
    fn another_aspect_ratio_is_refused() {
        let mut rectifier = Rectifier::new(calibration());
        let frame = RgbFrame {
            width_px: 640,
            height_px: 360,
            rgb: vec![0; 640 * 360 * 3],
        };
        let e = rectifier.rectify(&frame, 640, 360).unwrap_err();
        assert!(
            e.contains("calibrated at 640x480, the stream is 640x360"),
            "{e}"
        );
        let empty = RgbFrame {
            width_px: 0,
            height_px: 0,
            rgb: Vec::new(),
        };
        let e = rectifier.rectify(&empty, 640, 480).unwrap_err();
        assert!(e.contains("empty"), "{e}");
    }
}
