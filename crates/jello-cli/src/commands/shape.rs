//! `jello shape NAME OUT.obj`: writes one of the closed meshes the project makes itself (a torus,
//! a lumpy blob, a fluted jelly mould, a sphere, a capsule, an L) as OBJ, to voxelise with `jello create --mesh`. The example
//! scenes are made from these, so that no third-party model is needed.

use std::path::PathBuf;

use clap::Args;
use jello_core::formats::mesh::SHAPES;
use jello_core::TriMesh;

use crate::error::CliError;
use jello_io::{check_new_output, write_atomic};

/// Arguments of `jello shape`.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ShapeArgs {
    /// The shape: torus (a ring, genus 1), blob (a lumpy ball), mould (a fluted jelly mould on a
    /// flat base), sphere, capsule (1 m long along z, 0.5 m across) or ell (an L-shaped block,
    /// its arms 0.4 m thick, whatever the detail); each about 1 m across, centred on the z axis.
    #[arg(value_parser = clap::builder::PossibleValuesParser::new(SHAPES))]
    pub name: String,
    /// The OBJ file to write.
    #[arg(value_name = "OUT.obj")]
    pub out: PathBuf,
    /// Smoothness: 4·DETAIL segments around the z axis and 2·DETAIL rings (or tube segments).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(3..=200))]
    pub detail: u32,
    /// Scale (the shapes are about 1 m across at 1).
    #[arg(long, default_value_t = 1.0, value_parser = super::parse_positive)]
    pub size: f64,
    /// Overwrite OUT if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Writes the shape.
pub fn shape(args: ShapeArgs) -> Result<(), CliError> {
    let out = &args.out;
    check_new_output(out, args.force)?;
    let mut mesh = TriMesh::shape(&args.name, args.detail as usize)
        .expect("clap only lets known shape names through");
    if args.size != 1.0 {
        for v in &mut mesh.vertices {
            *v = *v * args.size;
        }
    }
    let size = if args.size == 1.0 {
        String::new()
    } else {
        format!(" --size {}", args.size)
    };
    let comment = format!(
        "{} made by `jello shape {} --detail {}{size}`: {} vertices, {} triangles, volume {:.6} m³",
        args.name,
        args.name,
        args.detail,
        mesh.vertices.len(),
        mesh.triangles.len(),
        mesh.volume()
    );
    write_atomic(out, mesh.to_obj(&comment).as_bytes())?;
    println!("{}: {comment}", out.display());
    Ok(())
}
