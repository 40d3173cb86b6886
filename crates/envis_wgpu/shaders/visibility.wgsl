// envis — shadow rays on the GPU: any-hit traversal of a flattened two-level BVH2 (twin of
// visibility::FlatBvh::occluded, step for step) and Möller–Trumbore (visibility::ray_triangle).
// The including module declares `bvh_nodes` and `bvh_triangles` (laid out as FlatBvh: the top
// level over instances first, then each mesh's BVH in object space; the instance records come
// first in bvh_triangles, two entries each: the rows of object_from_world, then its layers).

struct BvhNode {
    min: vec3<f32>,
    // Inner node: the first child (the second follows it); mesh leaf: the first triangle;
    // top-level leaf: the instance record (its transform; its layers follow).
    first: u32,
    max: vec3<f32>,
    // 0: inner node; mesh leaf: its triangle count; top-level leaf: its mesh's root node.
    count: u32,
}

// flat_bvh::STACK_SIZE.
const BVH_STACK_SIZE: u32 = 64u;
// visibility::Layers::ALL: every instance counts.
const ALL_LAYERS: u32 = 0xffffffffu;

// visibility::Layers::from_record: the layer bits, stored as two exact 16-bit halves.
fn instance_layers(r: array<vec4<f32>, 3>) -> u32 {
    return u32(r[0].x) | (u32(r[0].y) << 16u);
}

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

// visibility::ObjectFromWorld::point / vector.
fn to_object(m: array<vec4<f32>, 3>, p: vec3<f32>, w: f32) -> vec3<f32> {
    return vec3(dot(m[0].xyz, p) + m[0].w * w, dot(m[1].xyz, p) + m[1].w * w, dot(m[2].xyz, p) + m[2].w * w);
}

fn safe_inverse3(d: vec3<f32>) -> vec3<f32> {
    return vec3(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
}

// Whether a triangle of an instance on one of `layers` meets the ray with t in (t_min, t_max)
// (FlatBvh::occluded_on): the top level, and at each such instance its mesh with the ray in
// object space (t is the same in both).
fn bvh_occluded(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, node_count: u32, layers: u32) -> bool {
    if (node_count == 0u) {
        return false;
    }
    let inv = safe_inverse3(d);
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
            if ((instance_layers(bvh_triangles[n.first + 1u]) & layers) == 0u) {
                continue;
            }
            let m = bvh_triangles[n.first];
            if (blas_occluded(n.count, to_object(m, o, 1.0), to_object(m, d, 0.0), t_min, t_max)) {
                return true;
            }
        } else if (sp + 2u <= BVH_STACK_SIZE) {
            stack[sp] = n.first + 1u;
            stack[sp + 1u] = n.first;
            sp += 2u;
        }
    }
    return false;
}

// One mesh's BVH from its root, the ray in its object space.
fn blas_occluded(root: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    let inv = safe_inverse3(d);
    var stack: array<u32, BVH_STACK_SIZE>;
    stack[0] = root;
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
