//! Builds a scene in code — no scene file — renders it to an in-memory
//! image and writes it out.
//!
//! Run with: `cargo run --release --example render_in_code -- out.png`

use trazo::scene::desc::*;
use trazo::settings::Tonemap;
use trazo::{Rgb, Vec3};

fn main() -> Result<(), trazo::Error> {
    let output = std::env::args().nth(1).unwrap_or_else(|| "render_in_code.png".into());

    let mut desc = SceneDesc::default();
    desc.settings.width = 480;
    desc.settings.height = 320;
    desc.settings.spp = 16;
    desc.camera.from = Vec3::new(0.0, 1.5, 6.0);
    desc.camera.to = Vec3::new(0.0, 0.7, 0.0);
    desc.background = BackgroundDesc::Gradient {
        top: Rgb::new(0.5, 0.65, 0.9),
        bottom: Rgb::splat(0.2),
    };

    let red = MaterialDesc::classic(
        "red",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::new(0.8, 0.15, 0.1)),
            specular: ColorSource::Rgb(Rgb::splat(0.3)),
            shininess: 60.0,
            ..ClassicDesc::default()
        },
    );
    let gold = MaterialDesc::with_kind(
        "gold",
        MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Reflectance(Rgb::new(1.0, 0.78, 0.34)),
            tint: Rgb::ONE,
            roughness: (0.0, 0.0),
            distribution: MicrofacetDistribution::Ggx,
        },
    );
    desc.materials.extend([red, gold, MaterialDesc::new("floor")]);

    desc.lights.push(LightDesc::new(LightKind::Point {
        position: Vec3::new(-3.0, 5.0, 4.0),
        intensity: Rgb::splat(80.0),
        falloff: true,
    }));
    desc.shapes.push(ShapeDesc::new(
        ShapeKind::Sphere {
            center: Vec3::new(-0.9, 0.8, 0.0),
            radius: 0.8,
        },
        Some("red"),
    ));
    // A unit cube turned 30° and lifted onto the floor.
    desc.shapes.push(
        ShapeDesc::new(
            ShapeKind::Cuboid {
                min: Vec3::splat(-0.5),
                max: Vec3::splat(0.5),
            },
            Some("gold"),
        )
        .with(TransformOp::Rotate {
            axis: Vec3::Y,
            degrees: 30.0,
        })
        .with(TransformOp::Translate(Vec3::new(1.0, 0.5, 0.3))),
    );
    desc.shapes.push(ShapeDesc::new(
        ShapeKind::Plane {
            point: Vec3::ZERO,
            normal: Vec3::Y,
        },
        Some("floor"),
    ));

    let scene = trazo::scene::build(&desc)?;
    let image = trazo::render::render_image(&scene)?;
    println!("mean colour: {}", image.mean());
    trazo::film::io::write_image(std::path::Path::new(&output), &image, Tonemap::Clamp, 0.0)?;
    println!("wrote {output}");
    Ok(())
}
