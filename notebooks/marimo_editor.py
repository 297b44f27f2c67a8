import marimo

__generated_with = "0.25.2"
app = marimo.App(width="full")


@app.cell
def _():
    import marimo as mo

    import omniwidget as ow

    return mo, ow


@app.cell
def _(mo):
    mo.md("""
    # The omniwidget editor in marimo

    The bundled panorama, in the editor: draw a line with *Line* over an edge that should be
    straight, then *Rectify all lines*; *Save image* writes the result into the working
    folder (`hotel_room-rectified.jpg`) and offers it as a download. `?` lists the keys.
    """)
    return


@app.cell
def _(mo, ow):
    # mo.ui.anywidget makes the editor a UI element: a cell that reads `editor` runs again when
    # the browser changes it (a handle drawn or moved, the stage), as the one below does.
    editor = mo.ui.anywidget(ow.Editor(ow.sample_path(), height=440))
    editor
    return (editor,)


@app.cell
def _(editor, mo):
    _handles = editor.handles["handles"]
    _kinds = ", ".join(h["kind"] for h in _handles) or "none yet"
    mo.md(f"**Handles drawn:** {len(_handles)} ({_kinds}). `editor.document` is them as a `Handles`, `editor.result` the full-size result.")
    return


if __name__ == "__main__":
    app.run()
