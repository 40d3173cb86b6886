// envis — shadow rays on the GPU: any-hit traversal of a flattened BVH2 (twin of
// visibility::FlatBvh::occluded, step for step) and Möller–Trumbore (visibility::ray_triangle).
// The including module declares `bvh_nodes` and `bvh_triangles` (laid out as FlatBvh).

struct BvhNode {
    min: vec3<f32>,
    // Inner node: the first child (the second follows it); leaf: the first triangle.
    first: u32,
    max: vec3<f32>,
    // 0: inner node; otherwise the leaf's triangle count.
    count: u32,
}

// flat_bvh::STACK_SIZE.
const BVH_STACK_SIZE: u32 = 64u;

// visibility::ray_offset / shadow_origin: off the surface, on the side d leaves by.
fn shadow_origin(p: vec3<f32>, n: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let a = abs(p);
    let offset = 1e-4 * max(max(max(a.x, a.y), a.z), 1.0);
    return p + n * select(-offset, offset, dot(n, d) >= 0.0);
}

// obvhs's safe_inverse.
fn safe_inverse(x: f32) -> f32 {
    if (abs(x) <= 1.1920929e-7) {
        return sign(x) / 1.1920929e-7;
    }
    return 1.0 / x;
}

// The ray meets the box before t_max (obvhs's slab test).
fn bvh_slab(n: BvhNode, o: vec3<f32>, inv: vec3<f32>, t_max: f32) -> bool {
    let t1 = (n.min - o) * inv;
    let t2 = (n.max - o) * inv;
    let lo = min(t1, t2);
    let hi = max(t1, t2);
    let near = max(max(lo.x, lo.y), lo.z);
    let far = min(min(hi.x, hi.y), hi.z);
    return far >= near && far >= 0.0 && near < t_max;
}

// visibility::ray_triangle: the hit distance, or -1 when the ray misses the triangle.
fn ray_triangle(o: vec3<f32>, d: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let e1 = b - a;
    let e2 = c - a;
    let p = cross(d, e2);
    let det = dot(e1, p);
    if (abs(det) < 1e-12) {
        return -1.0;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = dot(s, p) * inv;
    if (u < 0.0 || u > 1.0) {
        return -1.0;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if (v < 0.0 || u + v > 1.0) {
        return -1.0;
    }
    return dot(e2, q) * inv;
}

// Whether any triangle meets the ray with t in (t_min, t_max).
fn bvh_occluded(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, node_count: u32) -> bool {
    if (node_count == 0u) {
        return false;
    }
    let inv = vec3(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
    var stack: array<u32, BVH_STACK_SIZE>;
    stack[0] = 0u;
    var sp = 1u;
    while (sp > 0u) {
        sp -= 1u;
        let n = bvh_nodes[stack[sp]];
        if (!bvh_slab(n, o, inv, t_max)) {
            continue;
        }
        if (n.count > 0u) {
            for (var k = n.first; k < n.first + n.count; k++) {
                let tri = bvh_triangles[k];
                let t = ray_triangle(o, d, tri[0].xyz, tri[1].xyz, tri[2].xyz);
                if (t > t_min && t < t_max) {
                    return true;
                }
            }
        } else if (sp + 2u <= BVH_STACK_SIZE) {
            stack[sp] = n.first + 1u;
            stack[sp + 1u] = n.first;
            sp += 2u;
        }
    }
    return false;
}
