//! `cssm check`: its flags, and the accuracy check's configuration they make.

use super::*;

#[derive(clap::Args)]
pub struct CheckArgs {
    /// The .cssm file.
    file: PathBuf,
    /// Scene (directory or mesh file) to check against. Default: the one recorded in the file.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Number of random surface point pairs.
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u64).range(1..))]
    pairs: u64,
    /// Seed of the pairs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Turn off percentage-closer filtering over the 2x2 pixels around each projection.
    #[arg(long)]
    no_pcf: bool,
    /// Use only the texel under each sender point (no filtering across neighbouring cube maps).
    #[arg(long)]
    no_sender_filter: bool,
    /// Ask only the sender's cube maps, as the paper does, instead of both points' (their
    /// answers weighted towards the end nearer the occluder; each pair's points both have
    /// texels, as in the runtime's radiosity and final gather).
    #[arg(long)]
    one_end: bool,
    /// Constant depth bias, in multiples of the bake's near distance.
    #[arg(long, default_value_t = QueryOptions::default().bias_near, value_parser = bias)]
    bias_near: f32,
    /// Depth bias proportional to the query depth.
    #[arg(long, default_value_t = QueryOptions::default().bias_relative, value_parser = bias)]
    bias_relative: f32,
    /// Exit with status 1 when the agreement over the pairs that exchange light is below this
    /// fraction.
    #[arg(long, value_parser = fraction)]
    min_agreement: Option<f64>,
    /// Print the result as one JSON object.
    #[arg(long)]
    json: bool,
    /// Move the rigid object NAME (an `[[objects]]` entry) before measuring, to translation
    /// X,Y,Z and, optionally, rotation RX,RY,RZ (degrees, as scene.toml's rotation_deg; its
    /// scale stays): visibility between moving objects (each object's own maps for itself,
    /// the others' coherent shadow maps) against ray casts of the moved scene. Repeatable.
    #[arg(long, value_name = "NAME=X,Y,Z[,RX,RY,RZ]", allow_hyphen_values = true, value_parser = parse_place)]
    place: Vec<Place>,
}

/// `--place NAME=X,Y,Z[,RX,RY,RZ]` of `cssm check`.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// The `[[objects]]` name.
    pub name: String,
    /// Its new translation.
    pub translation: glam::Vec3,
    /// Its new rotation, XYZ Euler angles in degrees (zero when not given).
    pub rotation_deg: glam::Vec3,
}

pub(super) fn parse_place(s: &str) -> Result<Place, String> {
    let Some((name, numbers)) = s.split_once('=') else {
        return Err(format!("'{s}' is not NAME=X,Y,Z[,RX,RY,RZ]"));
    };
    if name.is_empty() {
        return Err(format!("'{s}' names no object"));
    }
    let numbers: Vec<f32> = numbers
        .split(',')
        .map(finite_f32)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    let (translation, rotation) = match numbers[..] {
        [x, y, z] => ([x, y, z], [0.0; 3]),
        [x, y, z, a, b, c] => ([x, y, z], [a, b, c]),
        _ => {
            return Err(format!(
                "'{s}': expected 3 or 6 numbers after the name, got {}",
                numbers.len()
            ));
        }
    };
    Ok(Place {
        name: name.to_string(),
        translation: translation.into(),
        rotation_deg: rotation.into(),
    })
}

/// `cssm check`, as library types.
pub struct CheckConfig {
    /// The .cssm file.
    pub file: PathBuf,
    /// Scene directory or mesh file; `None`: the one recorded in the file.
    pub scene: Option<PathBuf>,
    /// Random surface point pairs.
    pub pairs: u64,
    /// Seed of the pairs.
    pub seed: u64,
    /// How the CSSM is queried.
    pub query: QueryOptions,
    /// Exit status 1 below this agreement over the pairs that exchange light.
    pub min_agreement: Option<f64>,
    /// `--json`.
    pub json: bool,
    /// `--place`: rigid objects moved before measuring.
    pub place: Vec<Place>,
}

impl CheckArgs {
    /// The query options and the rest, as the bake library's check takes them.
    pub fn config(self) -> CheckConfig {
        CheckConfig {
            file: self.file,
            scene: self.scene,
            pairs: self.pairs,
            seed: self.seed,
            query: QueryOptions {
                bias_near: self.bias_near,
                bias_relative: self.bias_relative,
                pcf: !self.no_pcf,
                sender_filter: !self.no_sender_filter,
                both_ends: !self.one_end,
            },
            min_agreement: self.min_agreement,
            json: self.json,
            place: self.place,
        }
    }
}
