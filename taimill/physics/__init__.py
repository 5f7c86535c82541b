"""The Taichi package: fields (`state`), the laws and frame as Taichi functions, walls,
the spatial hash and neighbour lists, the contact loop, the integrator, the kernels
(`engine`), loading a mill into the fields (`mill`) and the launcher (`runner`). Taichi
itself is reached only through the door, `physics.ti`, which picks the implementation
(taichi or taichi-forge) and runs `ti.init` inside `init_taichi`, never at import."""
