"""penumbra from Python: load Mitsuba 3 scenes, render them to numpy arrays, compare images
and run convergence ladders, with the CLI's defaults, determinism and error messages.

    >>> import penumbra
    >>> scene = penumbra.load("scenes/cornell-box.xml", res=64)
    >>> image = scene.render(spp=64, seed=0)        # (64, 64, 3) float32, linear RGB
    >>> penumbra.compare(image, "reference.exr", spp_a=64)["rmse"]

Errors in scenes, images and arguments raise ``penumbra.PenumbraError`` with the CLI's
one-line message (``ValueError`` for malformed Python arguments); Ctrl-C interrupts a render
with ``KeyboardInterrupt``.
"""

from ._penumbra import (
    PenumbraError,
    Scene,
    __version__,
    compare,
    load,
    read_exr,
    write_exr,
)
from ._penumbra import converge as _converge

__all__ = [
    "PenumbraError",
    "Scene",
    "__version__",
    "compare",
    "converge",
    "load",
    "read_exr",
    "write_exr",
]


def converge(
    scene,
    reference,
    spp,
    seeds=1,
    seed=None,
    sweep=None,
    threads=None,
    max_seconds=None,
    reference_spp=None,
    reference_variance=None,
    as_frame=None,
):
    """Error against ``reference`` along a ladder of cumulative sample counts ``spp``, as
    ``penumbra converge`` measures it: one record per (sweep value, seed, step) with
    ``label``, ``value``, ``seed``, ``spp``, ``seconds``, ``mpaths_per_second``, ``rmse``,
    ``mse``, ``rel_mse``, ``mae``, ``efficiency`` (1 / (seconds * MSE)) and ``z_pass_rate``.

    ``reference`` is a path to an OpenEXR file (its ``spp`` attribute and variance channels
    give the z-test) or an (H, W, 3) array with ``reference_spp`` and ``reference_variance``.
    ``sweep`` is ``"NAME=v1,v2,..."`` as ``--sweep`` takes it. ``max_seconds`` ends each
    ladder after the first step that takes that long.

    Returns a pandas DataFrame when pandas is installed and ``as_frame`` is not False, else
    a list of dicts (``as_frame=True`` requires pandas).
    """
    records = _converge(
        scene,
        reference,
        list(spp),
        seeds=seeds,
        seed=seed,
        sweep=sweep,
        threads=threads,
        max_seconds=max_seconds,
        reference_spp=reference_spp,
        reference_variance=reference_variance,
    )
    if as_frame is False:
        return records
    try:
        import pandas
    except ImportError:
        if as_frame:
            raise
        return records
    return pandas.DataFrame.from_records(records)
