//! GPU pieces every technique shares, each defined once: read-back, pass timing, the camera,
//! the G-buffer, the spot-light shadow map and tone mapping.

pub mod readback;
pub mod timestamps;
