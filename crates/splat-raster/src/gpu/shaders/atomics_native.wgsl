// Gradient accumulation with native f32 atomics (device feature SHADER_FLOAT32_ATOMIC).

@group(0) @binding(10) var<storage, read_write> grads: array<atomic<f32>>;

fn grad_add(i: u32, value: f32) {
    atomicAdd(&grads[i], value);
}
