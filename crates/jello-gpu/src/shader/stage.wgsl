// Where the forces read the stage they evaluate: `state_in`, in the module that steps a stage per
// dispatch (resident.wgsl defines these over workgroup memory instead).

fn position(i: u32) -> vec3<f32> {
    return state_in[2u * i].xyz;
}

fn velocity(i: u32) -> vec3<f32> {
    return state_in[2u * i + 1u].xyz;
}
