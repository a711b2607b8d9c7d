//! Stepping never allocates: every buffer lives in `Scratch`, sized once.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use jello_core::{
    step, Aabb, Control, ForceField, Integrator, ModelBuilder, Plane, Scratch, State, Vec3,
};

/// Counts the allocations each thread makes (the test harness allocates on threads of its own).
struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steps_do_not_allocate() {
    for integrator in Integrator::ALL {
        let field = ForceField::from_fn(5, Aabb::classic(), |p| Vec3::new(-p.y, p.x, -0.01) * 0.01)
            .unwrap();
        let plane = Plane::facing([0.0, 0.0, 1.0, 0.5], Vec3::ZERO).unwrap();
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(2e-4)
            .field(Some(field))
            .plane(Some(plane))
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(1.0, -2.0, -3.0));
        let control = Control {
            forces: vec![Vec3::new(0.0, 0.0, 0.001); 512],
        };
        let mut scratch = Scratch::new(&model);
        let before = ALLOCATIONS.with(Cell::get);
        for _ in 0..200 {
            step(&model, &mut state, &control, &mut scratch).unwrap();
        }
        let made = ALLOCATIONS.with(Cell::get) - before;
        assert_eq!(made, 0, "{integrator}: {made} allocations in 200 steps");
    }
}
