"""Work over collections: :mod:`~cagekit.batch.collection` finds and names the shapes of a
folder (or a synthetic family), :mod:`~cagekit.batch.amplify` makes variations of a
collection on a process pool or any ``concurrent.futures`` executor,
:mod:`~cagekit.batch.crossing` finds the parts of a variation that pass through each other,
:mod:`~cagekit.batch.sheet` draws a batch's contact sheet, and
:mod:`~cagekit.batch.cluster` connects to a Dask cluster for work beyond one machine. The
command is ``cagekit amplify``.
"""
