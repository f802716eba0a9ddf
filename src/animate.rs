//! `cssm render --animate`: the scene's animation (`[objects.animation]`, or the default spin)
//! rendered frame by frame with one persistent [`Renderer`], the objects moved between frames
//! by `set_object_transform`, into `DIR/frame-NNNN.png` and `DIR/animation.gif`.

use std::{
    io::{BufWriter, Write},
    path::{Path, PathBuf},
    process::ExitCode,
};

use cssm::formats::{self, ObjectKind, Scene};
use cssm::runtime::{self, common::readback};
use glam::{Affine3A, Vec3};

use crate::{
    CliResult, check_writable,
    cli::{AnimateOptions, RenderConfig},
    load_scene,
    render::{gpu_renderer, renderer_settings},
    scene_dir,
};

/// Seconds of one full turn of the default spin (no object has an animation of its own).
pub const DEFAULT_SPIN_SECONDS: f32 = 4.0;

/// Name of the animated image in the output directory.
const GIF_NAME: &str = "animation.gif";

/// How the scene's rigid objects move over time.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// The scene's own animations: each animated object follows its `pose_at`.
    Scene {
        /// The animated objects' indices into `Scene::objects`.
        objects: Vec<usize>,
        /// The longest object's duration, seconds.
        duration: f32,
    },
    /// No object has an animation: each rigid object turns about `axis` through its bounding
    /// box's centre, one full turn every [`DEFAULT_SPIN_SECONDS`].
    DefaultSpin {
        /// (object index, its centre in world space as loaded).
        objects: Vec<(usize, Vec3)>,
        /// Unit axis: the camera's up.
        axis: Vec3,
    },
}

impl Motion {
    /// The motion of `scene`: its animations where any object has one, else the default spin of
    /// every rigid object about the camera's up. `Err` when the scene has no rigid object.
    pub fn of(scene: &Scene) -> Result<Motion, String> {
        if let Some(duration) = scene.animation_duration() {
            let objects = (0..scene.objects.len())
                .filter(|&o| scene.objects[o].animation.is_some())
                .collect();
            return Ok(Motion::Scene { objects, duration });
        }
        let objects: Vec<(usize, Vec3)> = (0..scene.objects.len())
            .filter(|&o| scene.objects[o].kind == ObjectKind::Rigid)
            .map(|o| (o, scene.object_centre(o)))
            .collect();
        if objects.is_empty() {
            return Err(format!(
                "{}: --animate: the scene has no [[objects]] entry to move (give scene.toml an \
                 [[objects]] entry, optionally with [objects.animation]; docs/scene-format.md)",
                scene.path.display()
            ));
        }
        Ok(Motion::DefaultSpin {
            objects,
            axis: scene.camera.up.normalize(),
        })
    }

    /// Seconds the motion spans before it repeats (or ends).
    pub fn duration(&self) -> f32 {
        match self {
            Motion::Scene { duration, .. } => *duration,
            Motion::DefaultSpin { .. } => DEFAULT_SPIN_SECONDS,
        }
    }

    /// The moving objects' poses at `time` seconds: (object index, object-to-world transform).
    pub fn poses_at(&self, scene: &Scene, time: f32) -> Vec<(usize, Affine3A)> {
        match self {
            Motion::Scene { objects, .. } => objects
                .iter()
                .map(|&o| (o, scene.objects[o].pose_at(time)))
                .collect(),
            Motion::DefaultSpin { objects, axis } => {
                let angle = 360.0 * time / DEFAULT_SPIN_SECONDS;
                objects
                    .iter()
                    .map(|&(o, centre)| {
                        let turned = formats::scene::turned_about(
                            scene.objects[o].transform,
                            centre,
                            *axis,
                            angle,
                        );
                        (o, turned)
                    })
                    .collect()
            }
        }
    }

    /// What the motion is, for the command's message.
    fn describe(&self, scene: &Scene) -> String {
        let names = |objects: &mut dyn Iterator<Item = usize>| -> String {
            objects
                .map(|o| format!("`{}`", scene.objects[o].name))
                .collect::<Vec<_>>()
                .join(", ")
        };
        match self {
            Motion::Scene { objects, .. } => {
                format!("the animation of {}", names(&mut objects.iter().copied()))
            }
            Motion::DefaultSpin { objects, .. } => format!(
                "{} turning about the camera's up (no [objects.animation] in the scene)",
                names(&mut objects.iter().map(|(o, _)| *o))
            ),
        }
    }
}

/// `cssm render --time SECONDS`: every object of `scene`, each at its pose after `time` seconds
/// of the scene's motion ([`Motion::of`]; the objects that do not move at their loaded pose).
pub fn poses_at_time(scene: &Scene, time: f32) -> Result<Vec<Affine3A>, String> {
    let mut poses: Vec<Affine3A> = scene.objects.iter().map(|o| o.transform).collect();
    for (object, pose) in Motion::of(scene)?.poses_at(scene, time) {
        poses[object] = pose;
    }
    Ok(poses)
}

/// The file of frame `index`.
pub fn frame_name(index: u32) -> String {
    format!("frame-{index:04}.png")
}

/// `cssm render --animate`: every frame of the plan rendered with one renderer into `config.out`.
pub fn run_animate(config: &RenderConfig, options: &AnimateOptions) -> CliResult {
    let dir = scene_dir(config.scene.clone())?;
    let method = config.method;
    if !method.on_gpu() {
        return Err(format!(
            "--animate renders on the GPU; method '{method}' runs on the CPU and renders the \
             scene as loaded"
        ));
    }
    let scene = load_scene(&dir)?;
    let motion = Motion::of(&scene)?;
    let (frames, duration) = options.plan(motion.duration())?;
    let out = &config.out;
    let files = prepare_output(out, frames, options, &scene)?;
    let settings = renderer_settings(config, &scene, &dir)?;
    let (width, height) = (settings.frame.width, settings.frame.height);
    let (gpu, mut renderer, _) = gpu_renderer(config, &scene, &dir, &settings)?;
    let gpu_error = |e: runtime::RuntimeError| format!("{}: {e}", dir.display());
    let mut gif = if options.gif {
        Some(GifWriter::new(
            &out.join(GIF_NAME),
            width,
            height,
            duration / frames as f32,
        )?)
    } else {
        None
    };
    let bar = indicatif::ProgressBar::new(frames as u64).with_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:32}] {pos}/{len} frames, {elapsed}, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(format!("{} with {method} at {width}x{height}", scene.name));
    // One exposure for every frame, metered on the first: frames that flicker are no animation.
    let mut metered = None;
    for (index, path) in files.iter().enumerate() {
        let time = index as f32 * duration / frames as f32;
        for (object, pose) in motion.poses_at(&scene, time) {
            renderer
                .set_object_transform(object, pose)
                .map_err(|e| format!("{} at {time} s: {e}", dir.display()))?;
        }
        let mut image = readback::render_image(&mut renderer, 1).map_err(gpu_error)?;
        crate::render::expose(config, &mut image, &mut metered);
        readback::save_png(path, &image)?;
        if let Some(gif) = &mut gif {
            gif.push(image.display)?;
        }
        bar.inc(1);
    }
    gpu.wait().map_err(gpu_error)?;
    bar.finish_and_clear();
    if let Some(gif) = gif {
        gif.finish()?;
    }
    eprintln!(
        "rendered {} with {method} at {width}x{height} on {}: {}, {frames} frames over {duration} \
         s ({:.3} fps)",
        scene.name,
        gpu.describe(),
        motion.describe(&scene),
        frames as f32 / duration
    );
    eprintln!(
        "wrote {} .. {}{}",
        files[0].display(),
        files[files.len() - 1].display(),
        if options.gif {
            format!(", {}", out.join(GIF_NAME).display())
        } else {
            String::new()
        }
    );
    Ok(ExitCode::SUCCESS)
}

/// Creates `out` if missing and checks it before anything renders: a directory, writable, none
/// of the frames (nor the GIF) there already unless `--overwrite`, none of them an input of the
/// scene. Returns the frames' paths.
fn prepare_output(
    out: &Path,
    frames: u32,
    options: &AnimateOptions,
    scene: &Scene,
) -> Result<Vec<PathBuf>, String> {
    if out.exists() && !out.is_dir() {
        return Err(format!(
            "--out {}: --animate writes frames into a directory and this is a file",
            out.display()
        ));
    }
    // The frames' fixed names are never written through a link planted in OUT.
    let output = |name: &str| crate::out_path(out, name, false);
    let files = (0..frames)
        .map(|i| output(&frame_name(i)))
        .collect::<Result<Vec<PathBuf>, String>>()?;
    let mut outputs = files.clone();
    if options.gif {
        outputs.push(output(GIF_NAME)?);
    }
    let inputs = scene.input_files();
    for path in &outputs {
        check_writable(path, &inputs)?;
    }
    if !options.overwrite {
        let existing: Vec<&PathBuf> = outputs
            .iter()
            .filter(|p| p.symlink_metadata().is_ok())
            .collect();
        if let Some(first) = existing.first() {
            return Err(format!(
                "{} exists{}; pass --overwrite to replace the animation's files, or choose \
                 another --out",
                first.display(),
                match existing.len() - 1 {
                    0 => String::new(),
                    more => format!(" (and {more} more of this animation's files)"),
                }
            ));
        }
    }
    // Frames past this animation's last, from an earlier render, would read as part of it.
    let stale = (frames..)
        .take_while(|&i| out.join(frame_name(i)).exists())
        .count();
    if stale > 0 {
        eprintln!(
            "warning: {} also holds {stale} later frame(s) from an earlier render, from {} on; \
             they are not part of this animation",
            out.display(),
            frame_name(frames)
        );
    }
    Ok(files)
}

/// `animation.gif`, written frame by frame into the project's atomic file (an unnamed
/// temporary file in its directory, renamed into place when complete, as
/// `formats::cssm::write_bytes_atomic` writes): looping for ever, each frame shown for the
/// animation's frame time.
struct GifWriter {
    path: PathBuf,
    encoder: gif::Encoder<BufWriter<atomic_write_file::AtomicWriteFile>>,
    width: u16,
    height: u16,
    /// Seconds per frame: frame `i` is shown until `round(100 i frame_seconds)` hundredths
    /// of a second, so the rounding of one frame's delay is carried into the next.
    frame_seconds: f64,
    written: u32,
}

impl GifWriter {
    fn new(path: &Path, width: u32, height: u32, frame_seconds: f32) -> Result<Self, String> {
        let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let (Ok(w), Ok(h)) = (u16::try_from(width), u16::try_from(height)) else {
            return Err(fail(&format!(
                "a GIF is at most 65535 pixels a side, not {width}x{height}; pass --no-gif"
            )));
        };
        let target = formats::cssm::destination(path).map_err(|e| fail(&e))?;
        let file = atomic_write_file::AtomicWriteFile::options()
            .open(&target)
            .map_err(|e| fail(&e))?;
        let mut encoder =
            gif::Encoder::new(BufWriter::new(file), w, h, &[]).map_err(|e| fail(&e))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(|e| fail(&e))?;
        Ok(GifWriter {
            path: path.to_path_buf(),
            encoder,
            width: w,
            height: h,
            frame_seconds: frame_seconds as f64,
            written: 0,
        })
    }

    /// Appends a frame of RGBA8 pixels (quantised to its own palette).
    fn push(&mut self, mut rgba: Vec<u8>) -> Result<(), String> {
        let centiseconds = |i: u32| (i as f64 * self.frame_seconds * 100.0).round();
        let delay =
            (centiseconds(self.written + 1) - centiseconds(self.written)).clamp(1.0, 65535.0);
        // Speed 10 of NeuQuant's 1 (best) to 30: a good palette in a fraction of the time.
        let mut frame = gif::Frame::from_rgba_speed(self.width, self.height, &mut rgba, 10);
        frame.delay = delay as u16;
        self.encoder
            .write_frame(&frame)
            .map_err(|e| format!("{}: {e}", self.path.display()))?;
        self.written += 1;
        Ok(())
    }

    /// Writes the trailer, flushes, and renames the file into place.
    fn finish(self) -> Result<(), String> {
        let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", self.path.display());
        let mut writer = self.encoder.into_inner().map_err(|e| fail(&e))?;
        writer.flush().map_err(|e| fail(&e))?;
        let file = writer
            .into_inner()
            .map_err(|e| fail(&e.error().to_string()))?;
        file.commit().map_err(|e| fail(&e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(frames: Option<u32>, fps: Option<f32>, duration: Option<f32>) -> AnimateOptions {
        AnimateOptions {
            frames,
            fps,
            duration,
            overwrite: false,
            gif: true,
        }
    }

    #[test]
    fn the_plan_takes_two_of_frames_fps_and_duration() {
        // Defaults: 24 fps over the scene's duration.
        assert_eq!(options(None, None, None).plan(2.0), Ok((48, 2.0)));
        assert_eq!(options(Some(3), None, None).plan(2.0), Ok((3, 2.0)));
        assert_eq!(options(None, Some(10.0), None).plan(2.0), Ok((20, 2.0)));
        assert_eq!(options(None, None, Some(0.5)).plan(2.0), Ok((12, 0.5)));
        assert_eq!(options(Some(8), Some(4.0), None).plan(2.0), Ok((8, 2.0)));
        assert_eq!(options(Some(5), None, Some(1.0)).plan(2.0), Ok((5, 1.0)));
        assert_eq!(options(None, Some(2.0), Some(3.0)).plan(9.0), Ok((6, 3.0)));
        // A very short animation still has a frame.
        assert_eq!(options(None, None, None).plan(0.01), Ok((1, 0.01)));
        let e = options(Some(5), Some(2.0), Some(1.0))
            .plan(2.0)
            .unwrap_err();
        assert!(e.contains("at most two"), "{e}");
        let e = options(None, Some(1000.0), Some(10.0))
            .plan(2.0)
            .unwrap_err();
        assert!(e.contains("10000 frames") && e.contains("4096"), "{e}");
        let e = options(Some(3), None, None).plan(0.0).unwrap_err();
        assert!(e.contains("--duration"), "{e}");
    }

    /// A scene of a static quad and one rigid triangle (two with `animated`), loaded from `dir`.
    fn scene(dir: &Path, animation: &str) -> Scene {
        let quad = "v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 2 3 4\n";
        let tri = "v 0 0 0\nv 2 0 0\nv 0 2 0\nf 1 2 3\n";
        std::fs::write(dir.join("quad.obj"), quad).unwrap();
        std::fs::write(dir.join("tri.obj"), tri).unwrap();
        std::fs::write(
            dir.join("scene.toml"),
            format!(
                "mesh = \"quad.obj\"\n[camera]\nposition = [0.0, 5.0, 10.0]\n\
                 target = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y_deg = 40.0\n\
                 resolution = [32, 24]\n\n[[objects]]\nname = \"a\"\nmesh = \"tri.obj\"\n\
                 translation = [1.0, 0.0, 0.0]\n\n[[objects]]\nname = \"b\"\n\
                 mesh = \"tri.obj\"\n{animation}"
            ),
        )
        .unwrap();
        Scene::load(dir).unwrap()
    }

    #[test]
    fn without_animations_every_rigid_object_spins_about_its_centre() {
        let dir = tempfile::tempdir().unwrap();
        let s = scene(dir.path(), "");
        let motion = Motion::of(&s).unwrap();
        assert_eq!(motion.duration(), DEFAULT_SPIN_SECONDS);
        let Motion::DefaultSpin { objects, axis } = &motion else {
            panic!("{motion:?}")
        };
        assert_eq!(*axis, Vec3::Y);
        assert_eq!(objects[0], (1, Vec3::new(2.0, 1.0, 0.0)));
        assert_eq!(objects[1], (2, Vec3::new(1.0, 1.0, 0.0)));
        // A quarter turn after a quarter of the period: the centre stays, the rest turns.
        let poses = motion.poses_at(&s, DEFAULT_SPIN_SECONDS / 4.0);
        assert_eq!(poses.len(), 2);
        let (o, pose) = poses[0];
        assert_eq!(o, 1);
        let loaded = s.objects[1].transform;
        let moved = |p: Vec3| pose.transform_point3(loaded.inverse().transform_point3(p));
        assert!(moved(Vec3::new(2.0, 1.0, 0.0)).distance(Vec3::new(2.0, 1.0, 0.0)) < 1e-5);
        // (3, 0, 0) is 1 along +x from the centre's column: a quarter turn about +y takes it to -z.
        assert!(moved(Vec3::new(3.0, 0.0, 0.0)).distance(Vec3::new(2.0, 0.0, -1.0)) < 1e-5);
        // At 0 s the objects are where they were loaded.
        for (o, pose) in motion.poses_at(&s, 0.0) {
            assert!(pose.abs_diff_eq(s.objects[o].transform, 1e-6));
        }
    }

    #[test]
    fn with_an_animation_only_the_animated_objects_move() {
        let dir = tempfile::tempdir().unwrap();
        let s = scene(
            dir.path(),
            "[objects.animation]\nkeyframes = [{ time = 0.0 }, \
             { time = 3.0, translation = [0.0, 0.0, 6.0] }]\n",
        );
        let motion = Motion::of(&s).unwrap();
        assert_eq!(
            motion,
            Motion::Scene {
                objects: vec![2],
                duration: 3.0
            }
        );
        let poses = motion.poses_at(&s, 1.0);
        assert_eq!(poses.len(), 1);
        assert!(
            poses[0]
                .1
                .translation
                .distance(Vec3::new(0.0, 0.0, 2.0).into())
                < 1e-5
        );
    }

    #[test]
    fn a_scene_without_rigid_objects_has_nothing_to_animate() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("tri.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let s = Scene::load(dir.path()).unwrap();
        let e = Motion::of(&s).unwrap_err();
        assert!(e.contains("no [[objects]] entry to move"), "{e}");
    }

    #[test]
    fn gif_frames_are_written_whole_and_renamed_into_place() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(GIF_NAME);
        let mut gif = GifWriter::new(&path, 4, 2, 1.0 / 24.0).unwrap();
        for v in [0u8, 128, 255] {
            gif.push(vec![v; 4 * 2 * 4]).unwrap();
            assert!(!path.exists(), "the GIF appears only when complete");
        }
        gif.finish().unwrap();
        let entries: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(entries.len(), 1, "no temporary file left");
        let mut decoder = gif::DecodeOptions::new();
        decoder.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = decoder
            .read_info(std::fs::File::open(&path).unwrap())
            .unwrap();
        let (mut frames, mut delays, mut firsts) = (0, Vec::new(), Vec::new());
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            frames += 1;
            delays.push(frame.delay);
            firsts.push(frame.buffer[0]);
        }
        assert_eq!(frames, 3);
        // 1/24 s in hundredths: 4, 4, 5 (the rounding carried, 12.5 cs in all).
        assert_eq!(delays.iter().map(|&d| d as u32).sum::<u32>(), 13);
        assert!(delays.iter().all(|&d| d == 4 || d == 5), "{delays:?}");
        assert!(
            firsts[0] < 10 && (118..138).contains(&firsts[1]) && firsts[2] > 245,
            "{firsts:?}"
        );
    }
}
