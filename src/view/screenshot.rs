//! Screenshots (F12, `--screenshot`, a script's `screenshot`): the renderer's image read back,
//! byte for byte what `cssm render` writes for the same flags, which it prints.

use super::*;

impl App {
    /// F12: the first free `cssm-view-NNNN.png` in the current directory (and `.exr` with
    /// `--shot-exr`).
    pub(super) fn f12(&mut self) -> Result<(), String> {
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let (png, exr) = loop {
            let stem = format!("cssm-view-{:04}", gfx.shots);
            gfx.shots += 1;
            let (png, exr) = (
                PathBuf::from(format!("{stem}.png")),
                PathBuf::from(format!("{stem}.exr")),
            );
            if !png.exists() && !exr.exists() {
                break (png, exr);
            }
        };
        self.screenshot(&png)?;
        if self.view.shot_exr {
            self.screenshot(&exr)?;
        }
        Ok(())
    }

    /// Writes the last frame's image to `path`: the tone-mapped PNG, or with the extension
    /// `.exr` the linear radiance as `cssm render --exr` writes it; then prints the flags with
    /// which `cssm render` writes the same file.
    pub(super) fn screenshot(&mut self, path: &Path) -> Result<(), String> {
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let (w, h) = (gfx.image.width(), gfx.image.height());
        let fail = |e: runtime::RuntimeError| format!("{}: {e}", path.display());
        let exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if exr {
            let bytes = readback::read_texture(
                &gfx.gpu.device,
                &gfx.gpu.queue,
                gfx.renderer.radiance(),
                16,
            )
            .map_err(fail)?;
            let radiance: Vec<[f32; 4]> = readback::vec4s(&bytes)
                .iter()
                .map(|v| v.to_array())
                .collect();
            readback::save_radiance_exr(path, w, h, &radiance)?;
        } else {
            let rgba = readback::read_texture(&gfx.gpu.device, &gfx.gpu.queue, &gfx.image, 4)
                .map_err(fail)?;
            readback::save_rgba_png(path, w, h, rgba)?;
        }
        let frames = gfx.renderer.frames_accumulated();
        eprintln!(
            "wrote {} ({}, {frames} frames)",
            path.display(),
            self.view.describe(),
        );
        eprintln!(
            "render flags for {}: {} --{} {}",
            path.display(),
            self.view.render_flags(frames),
            if exr { "exr" } else { "out" },
            path.display()
        );
        Ok(())
    }
}
