//! Sharded renders: the films of a render's shards, merged in any order,
//! are the film of the render on one machine, bit for bit.

use trazo::film::Film;
use trazo::render::{RenderOptions, RenderStats, Shard, render};
use trazo::scene::builtin::cornell_box;
use trazo::settings::{Filter, IntegratorKind};

fn film_of(desc: &trazo::scene::SceneDesc, threads: usize, shard: Option<Shard>, aovs: bool) -> (Film, RenderStats) {
    let scene = trazo::scene::build(desc).unwrap();
    let out = render(
        &scene,
        &RenderOptions {
            threads: Some(threads),
            tile_size: 8,
            aovs,
            shard,
            ..RenderOptions::default()
        },
    )
    .unwrap();
    (out.film, out.stats)
}

fn check_shards_merge_exactly(desc: &trazo::scene::SceneDesc, count: u32, aovs: bool) {
    let (whole, stats) = film_of(desc, 2, None, aovs);
    assert_eq!(stats.spp, desc.settings.spp);
    let mut parts: Vec<(Film, RenderStats)> = (0..count)
        .map(|index| film_of(desc, 1 + index as usize % 2, Some(Shard { index, count }), aovs))
        .collect();
    let spp: u32 = parts.iter().map(|p| p.1.spp).sum();
    assert_eq!(spp, desc.settings.spp);
    // Any order of merging.
    parts.reverse();
    let mut merged = Film::new(whole.width, whole.height);
    if aovs {
        merged.aovs = Some(vec![Default::default(); whole.pixels.len()]);
    }
    for (film, _) in &parts {
        // A shard alone is a whole image: every pixel has samples.
        assert!(film.pixels.iter().all(|p| p.weight() > 0.0));
        merged.merge(film).unwrap();
    }
    assert!(merged == whole, "the merged film differs from the single render's");
    assert_eq!(merged.to_image(), whole.to_image());
    // Fewer shards are a noisier image of the same scene, not another.
    let mut two = parts[0].0.clone();
    two.merge(&parts[1].0).unwrap();
    let (a, b) = (two.to_image().mean(), whole.to_image().mean());
    assert!((a - b).abs().max_element() < 0.1 * b.max_element(), "{a} vs {b}");
}

#[test]
fn shards_of_a_path_traced_render_merge_into_it() {
    let mut desc = cornell_box();
    desc.settings.width = 24;
    desc.settings.height = 20;
    desc.settings.spp = 40;
    check_shards_merge_exactly(&desc, 4, true);
}

#[test]
fn shards_merge_exactly_with_a_splatting_filter() {
    let mut desc = cornell_box();
    desc.settings.width = 20;
    desc.settings.height = 16;
    desc.settings.spp = 24;
    desc.settings.filter = Filter::Gaussian {
        stddev: 0.5,
        radius: 2.0,
    };
    check_shards_merge_exactly(&desc, 3, false);
}

#[test]
fn shards_of_a_photon_mapped_render_merge_into_it() {
    let mut desc = cornell_box();
    desc.settings.width = 16;
    desc.settings.height = 16;
    desc.settings.spp = 8;
    desc.settings.integrator = IntegratorKind::Photon;
    desc.settings.photon.photons = 20_000;
    check_shards_merge_exactly(&desc, 2, false);
}

#[test]
fn progressive_photon_mapping_cannot_be_sharded() {
    let mut desc = cornell_box();
    desc.settings.width = 8;
    desc.settings.height = 8;
    desc.settings.spp = 4;
    desc.settings.integrator = IntegratorKind::Sppm;
    let scene = trazo::scene::build(&desc).unwrap();
    let options = RenderOptions {
        shard: Some(Shard { index: 0, count: 2 }),
        ..RenderOptions::default()
    };
    assert!(render(&scene, &options).is_err());
}
