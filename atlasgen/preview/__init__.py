"""``atlasgen preview``: one material, or a contact sheet of several, on a standard ball, re-rendered on every save.

:mod:`.scene` is the standard scene, :mod:`.label` the text under each picture, :mod:`.sheet` the
grid of several, :mod:`.previewer` the bake-and-render on a renderer kept warm, and :mod:`.watch`
the loop that re-renders when a material file changes (watchfiles, imported only there).
"""
