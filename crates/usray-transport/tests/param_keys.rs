//! Parameter keys: every key of every shipped scene prints as its dotted path
//! and parses back to itself, reads the scene's value, and is declared with
//! the group and default range of its kind.

mod common;
use common::scene_path;
use usray_transport::scene::{ParamGroup, ParamKey};
use usray_transport::{Field, Scene};

fn shipped() -> Vec<Scene> {
    [
        "cylinder",
        "ring",
        "phantom",
        "valve",
        "phased_ring",
        "convex_rod",
    ]
    .iter()
    .map(|n| Scene::load(scene_path(&format!("{n}.toml"))).unwrap())
    .collect()
}

#[test]
fn every_key_round_trips_through_its_path() {
    for s in shipped() {
        let params = s.params();
        assert!(!params.is_empty());
        for (key, v) in params {
            let path = key.to_string();
            assert_eq!(path.parse::<ParamKey>().unwrap(), key, "{path}");
            assert_eq!(s.key(&path).unwrap(), key, "{path}");
            assert_eq!(s.get(&key).unwrap().to_bits(), v.to_bits(), "{path}");
            let mut t = s.clone();
            t.set(&key, v).unwrap();
            assert_eq!(t, s, "{path}");
        }
    }
}

#[test]
fn paths_parse_only_as_printed() {
    let s = Scene::load(scene_path("cylinder.toml")).unwrap();
    for bad in [
        "objects.cylinder.center_m.02",
        "objects.cylinder.center_m.+1",
        "objects.cylinder.center_m",
        "objects.cylinder.radius_m.0",
        "objects.cylinder.center_m.3",
        "objects..radius_m",
        "probe.roughness",
        "medium.sound_speed_m_s ",
        "",
    ] {
        let e = s.key(bad).unwrap_err();
        assert_eq!(e.key, bad);
        assert!(e.message.contains("usray params SCENE"), "{e}");
    }
}

#[test]
fn kinds_carry_their_group_and_default_range() {
    let k = |p: &str| p.parse::<ParamKey>().unwrap();
    assert_eq!(k("objects.c.center_m.2").group(), ParamGroup::Geometry);
    assert_eq!(k("objects.c.thickness_m").group(), ParamGroup::Material);
    assert_eq!(k("probe.radius_m").group(), ParamGroup::Acquisition);
    assert_eq!(
        k("materials.t.sound_speed_m_s").group(),
        ParamGroup::Acquisition
    );
    assert_eq!(k("medium.impedance_mrayl").group(), ParamGroup::Material);
    assert_eq!(k("materials.t.roughness").default_range(0.3), (0.01, 1.0));
    assert_eq!(k("objects.c.radius_m").default_range(0.005), (0.003, 0.007));
    assert_eq!(k("objects.c.thickness_m").default_range(1e-3), (0.0, 5e-3));
    assert_eq!(k("probe.cycles").default_range(3.0), (1.5, 6.0));
    assert_eq!(
        k("acquisition.depth_gain_db_per_cm").default_range(1.0),
        (-2.0, 4.0)
    );
    assert_eq!(k("objects.c.scale").default_range(1.0), (0.0, 2.0));
    assert!(k("materials.t.attenuation_db_cm_mhz").is_attenuation());
    assert_eq!(
        k("materials.a.b.roughness"),
        ParamKey::material("a.b", Field::Roughness)
    );
}

/// A refused step leaves the scene as it was, bit for bit: values set before
/// the bad one, a wall projected under its radius and a key given twice are
/// all put back.
#[test]
fn a_refused_step_leaves_the_scene_unchanged() {
    let s = Scene::load(scene_path("ring.toml")).unwrap();
    let wall = s.key("objects.tube.thickness_m").unwrap();
    let radius = s.key("objects.tube.radius_m").unwrap();
    let pitch = s.key("probe.pitch_m").unwrap();
    let r = s.get(&radius).unwrap();
    let mut t = s.clone();
    let e = t
        .set_projected(&[(&wall, 1.5 * r), (&pitch, 0.5e-3), (&pitch, -1.0)])
        .unwrap_err();
    assert_eq!(e.key, "probe.pitch_m", "{e}");
    assert_eq!(t, s);
    let nope = ParamKey::object("nope", Field::Radius);
    let e = t
        .set_projected(&[(&wall, 1.5 * r), (&nope, 1.0)])
        .unwrap_err();
    assert_eq!(e.key, "objects.nope.radius_m", "{e}");
    assert_eq!(t, s);
    // Accepted, the wall is projected and the last value of a key wins.
    t.set_projected(&[(&wall, 1.5 * r), (&pitch, 0.4e-3), (&pitch, 0.5e-3)])
        .unwrap();
    assert_eq!(t.get(&pitch).unwrap(), 0.5e-3);
    assert_eq!(
        t.get(&wall).unwrap(),
        usray_transport::scene::params::MAX_WALL_FRACTION * r
    );
}
