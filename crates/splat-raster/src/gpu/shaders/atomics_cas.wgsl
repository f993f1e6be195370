// Gradient accumulation without f32 atomics: a compare-exchange loop on the bit pattern.

@group(0) @binding(10) var<storage, read_write> grads: array<atomic<u32>>;

fn grad_add(i: u32, value: f32) {
    var old = atomicLoad(&grads[i]);
    loop {
        let next = bitcast<u32>(bitcast<f32>(old) + value);
        let r = atomicCompareExchangeWeak(&grads[i], old, next);
        if r.exchanged {
            break;
        }
        old = r.old_value;
    }
}
