//! What the mesh fuzz targets check: anything that parses is the closed, outward surface of a
//! solid, and anything that does not gives a clean error. (Each target uses part of it.)

#![allow(dead_code)]

use std::collections::HashMap;

use jello_core::{MeshError, TriMesh, Vec3};

/// Asserts what every parsed mesh must satisfy: at least one triangle, finite coordinates,
/// indices in range, three distinct corners of non-zero cross product, every vertex used,
/// every directed edge once and its reverse once, and a finite positive volume.
pub fn assert_solid(m: &TriMesh) {
    assert!(!m.triangles.is_empty(), "no triangles");
    assert!(
        m.vertices.iter().all(|p| p.is_finite()),
        "non-finite vertex"
    );
    let mut used = vec![false; m.vertices.len()];
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &m.triangles {
        for &i in t {
            assert!(
                (i as usize) < m.vertices.len(),
                "index out of range in {t:?}"
            );
            used[i as usize] = true;
        }
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
            "degenerate {t:?}"
        );
        let [a, b, c] = t.map(|i| m.vertices[i as usize]);
        assert!((b - a).cross(c - a) != Vec3::ZERO, "zero area {t:?}");
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    assert!(used.iter().all(|&u| u), "unused vertex");
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "edge {a}→{b} used {n} times");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge {a}→{b} has no reverse"
        );
    }
    let v = m.volume();
    assert!(v.is_finite() && v > 0.0, "volume {v}");
    let (lo, hi) = m.bounds();
    assert!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z);
}

/// Asserts an error names the source, displays as "name:line: message" or "name: message", and
/// has a short message at a line that exists.
pub fn assert_clean_error(e: &MeshError, name: &str, data: &[u8]) {
    assert_eq!(e.source_name, name);
    let shown = e.to_string();
    let prefix = if e.line > 0 {
        format!("{name}:{}: ", e.line)
    } else {
        format!("{name}: ")
    };
    assert!(shown.starts_with(&prefix), "{shown}");
    assert!(!e.message.is_empty());
    assert!(
        e.message.len() < 2000,
        "message of {} bytes",
        e.message.len()
    );
    let lines = data.iter().filter(|&&b| b == b'\n').count() + 1;
    assert!(e.line <= lines, "line {} of {lines}: {shown}", e.line);
}

/// The coordinates' bits, so that a comparison tells -0 from 0.
pub fn bits(m: &TriMesh) -> (Vec<[u64; 3]>, &[[u32; 3]]) {
    let v = m
        .vertices
        .iter()
        .map(|p| p.to_array().map(f64::to_bits))
        .collect();
    (v, &m.triangles)
}

/// The mesh as OBJ text, every number in shortest round-trip form.
pub fn to_obj(m: &TriMesh) -> String {
    let mut s = String::new();
    for p in &m.vertices {
        s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    for t in &m.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

/// The mesh as ASCII STL, every number in shortest round-trip form (normals zero).
pub fn to_ascii_stl(m: &TriMesh) -> String {
    let mut s = String::from("solid fuzz\n");
    for t in &m.triangles {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for &i in t {
            let p = m.vertices[i as usize];
            s.push_str(&format!("vertex {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid fuzz\n");
    s
}

/// The mesh as binary STL, when every coordinate is an `f32`.
pub fn to_binary_stl(m: &TriMesh) -> Option<Vec<u8>> {
    let exact = |c: f64| c as f32 as f64 == c;
    if !m
        .vertices
        .iter()
        .all(|p| p.to_array().into_iter().all(exact))
    {
        return None;
    }
    let mut out = vec![0; 80];
    out.extend((m.triangles.len() as u32).to_le_bytes());
    for t in &m.triangles {
        out.extend([0; 12]);
        for &i in t {
            for c in m.vertices[i as usize].to_array() {
                out.extend((c as f32).to_le_bytes());
            }
        }
        out.extend([0; 2]);
    }
    Some(out)
}

/// The mesh with its vertices renumbered in the order the triangles first use them (what STL's
/// welding gives).
pub fn renumbered_by_first_use(m: &TriMesh) -> TriMesh {
    let mut new_of = vec![u32::MAX; m.vertices.len()];
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for t in &m.triangles {
        triangles.push(t.map(|old| {
            if new_of[old as usize] == u32::MAX {
                new_of[old as usize] = vertices.len() as u32;
                vertices.push(m.vertices[old as usize]);
            }
            new_of[old as usize]
        }));
    }
    TriMesh {
        vertices,
        triangles,
    }
}
