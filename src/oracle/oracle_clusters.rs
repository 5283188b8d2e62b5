//! Occludees below object level: each object's triangles as a tree of
//! clusters with their boxes (median cuts along the longest side of the
//! triangles' centres). An object whose box is not proved hidden may still
//! be, cluster by cluster: it is hidden when every leaf cluster's box is
//! (a leaf holds all of its triangles), and the search stops at the first
//! leaf that is not, so a visible object costs one path down the tree.

use glam::DVec3;

use crate::scene::Scene;

/// One cluster of an object's triangles.
#[derive(Clone, Debug)]
pub struct Cluster {
    /// The box of its triangles.
    pub min: DVec3,
    /// The box of its triangles.
    pub max: DVec3,
    /// Its two halves (indices into the object's clusters), or none for a
    /// leaf.
    pub children: Option<[u32; 2]>,
}

/// The cluster tree of every object, the root first; empty for objects of
/// fewer than two triangles or when `depth` is 0.
pub fn build(scene: &Scene, depth: usize) -> Vec<Vec<Cluster>> {
    (0..scene.objects().len())
        .map(|o| {
            let tris = scene.object_triangles(o);
            if depth == 0 || tris.len() < 2 {
                return Vec::new();
            }
            let mut items: Vec<(DVec3, DVec3, DVec3)> = tris
                .iter()
                .map(|t| {
                    let p = t.map(|v| v.as_dvec3());
                    let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
                    (lo, hi, (p[0] + p[1] + p[2]) / 3.0)
                })
                .collect();
            let mut out = Vec::new();
            split(&mut items, depth, &mut out);
            out
        })
        .collect()
}

/// Appends the cluster of `items` and, below `depth` levels, its halves;
/// returns its index.
fn split(items: &mut [(DVec3, DVec3, DVec3)], depth: usize, out: &mut Vec<Cluster>) -> u32 {
    let (min, max) = items
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), t| {
            (a.min(t.0), b.max(t.1))
        });
    let at = out.len() as u32;
    out.push(Cluster {
        min,
        max,
        children: None,
    });
    if depth > 1 && items.len() >= 2 {
        let (clo, chi) = items
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), t| {
                (a.min(t.2), b.max(t.2))
            });
        let e = chi - clo;
        let axis = if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        };
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |a, b| a.2[axis].total_cmp(&b.2[axis]));
        let (left, right) = items.split_at_mut(mid);
        let a = split(left, depth - 1, out);
        let b = split(right, depth - 1, out);
        out[at as usize].children = Some([a, b]);
    }
    at
}

/// Whether `hidden` proves every leaf cluster below `root` of `clusters`
/// hidden, testing a cluster's halves only when the cluster itself is not
/// proved hidden, and stopping at the first leaf that is not.
pub fn hidden_below(
    clusters: &[Cluster],
    root: u32,
    hidden: &mut dyn FnMut(DVec3, DVec3) -> bool,
) -> bool {
    let mut stack = vec![root];
    while let Some(k) = stack.pop() {
        let c = &clusters[k as usize];
        if hidden(c.min, c.max) {
            continue;
        }
        match c.children {
            Some([a, b]) => stack.extend([b, a]),
            None => return false,
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn leaves_hold_every_triangle_and_the_search_stops_early() {
        let mut b = crate::scene::SceneBuilder::new(crate::scene::SceneFormat::Procedural);
        b.begin_object("row".to_string());
        for k in 0..16 {
            let x = k as f32;
            b.push_triangle([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 0.5, 0.0, 0.0),
                Vec3::new(x, 0.5, 0.0),
            ])
            .unwrap();
        }
        let scene = b.finish(std::path::Path::new("row")).unwrap();
        let trees = build(&scene, 3);
        let tree = &trees[0];
        assert_eq!(tree.len(), 7);
        // Every triangle lies in some leaf's box.
        for t in scene.object_triangles(0) {
            assert!(tree.iter().filter(|c| c.children.is_none()).any(|c| {
                t.iter()
                    .all(|v| v.as_dvec3().cmpge(c.min).all() && v.as_dvec3().cmple(c.max).all())
            }));
        }
        // Hidden only where x < 8: the left half's leaves pass, the right
        // half's first leaf fails and ends the search.
        let mut tested = 0;
        let hidden = hidden_below(tree, 0, &mut |_, max| {
            tested += 1;
            max.x < 8.0
        });
        assert!(!hidden);
        assert!(tested <= 6, "{tested} tests");
        assert!(hidden_below(tree, 0, &mut |_, max| max.x < 100.0));
        assert!(build(&scene, 0)[0].is_empty());
    }
}
