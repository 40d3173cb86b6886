// envis — a batch of shadow rays through visibility.wgsl (the CPU-twin tests and benchmarks).
// Needs visibility.wgsl before it.

struct Ray {
    // xyz: origin; w: t_min.
    o: vec4<f32>,
    // xyz: direction; w: t_max.
    d: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(1) var<storage, read> bvh_triangles: array<array<vec4<f32>, 3>>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
// One per ray: 1 blocked, 0 free.
@group(0) @binding(3) var<storage, read_write> blocked: array<u32>;
// x: node count; y: ray count; z: the layers the rays are cast for (visibility::Layers).
@group(0) @binding(4) var<uniform> counts: vec4<u32>;

@compute @workgroup_size(64)
fn trace_rays(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= counts.y) {
        return;
    }
    let r = rays[i];
    blocked[i] = select(0u, 1u, bvh_occluded(r.o.xyz, r.d.xyz, r.o.w, r.d.w, counts.x, counts.z));
}
