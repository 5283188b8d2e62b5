//! The real scenes of `../shared/scenes/` load with the object and triangle
//! counts their README gives (its triangle counts include the zero-area
//! triangles that loading drops). Skipped where the folder is absent.

use vis5d::scene;

#[test]
fn real_scenes_load_with_the_documented_counts() {
    let table = [
        ("apartment_morse/apartment.obj", 33, 10_616),
        ("apartment_ifc_duplex/duplex_apartment.obj", 215, 26_348),
        ("house_ifc_fzk_haus/AC14-FZK-Haus.obj", 110, 36_290),
        ("hall_morse_grande_salle/grande_salle.obj", 39, 43_296),
        ("city_san_francisco/san_francisco.obj", 2_368, 268_041),
        ("forest_morse_land1_trees/land1_trees.obj", 27, 766_660),
    ];
    let root = crate::shared_scenes();
    if !root.exists() {
        eprintln!("skipped: {} is not here", root.display());
        return;
    }
    for (file, objects, triangles) in table {
        let s = scene::load(root.join(file)).unwrap();
        s.validate().unwrap();
        assert_eq!(s.objects().len(), objects, "{file}");
        assert_eq!(
            s.triangles().len() + s.report().dropped_degenerate,
            triangles,
            "{file}"
        );
    }
}
