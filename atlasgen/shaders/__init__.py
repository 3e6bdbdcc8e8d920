"""Every piece of shader code atlasgen writes, one module per emitted unit, and the renderer's WGSL files.

:mod:`.lang` (the declarations and their WGSL, GLSL and HLSL emitters), :mod:`.structs`
(CPU/GPU structs and the WGSL layout rules), :mod:`.specular` (the renderer's specular lobe),
:mod:`.separable` and :mod:`.separable_analytic` (a separable material's rebuild and the
closed-form baseline), :mod:`.include` (the generated include's assembly) and :mod:`.passes`
(the renderer's passes from the ``*.wgsl`` files here, shipped as package data). The package
sits above ``separable/`` and below ``models/``: code from higher layers (a model's own include
code, the renderer's shared structs) is handed in by its caller, never imported. The NumPy
formulas the shaders mirror stay in ``optics/`` and ``separable/``. Nothing is imported here.
"""
