"""Work over collections: :mod:`~cagekit.batch.collection` finds and names the shapes of a
folder (or a synthetic family), :mod:`~cagekit.batch.amplify` makes variations of a
collection on a process pool or any ``concurrent.futures`` executor, and
:mod:`~cagekit.batch.cluster` connects to a Dask cluster for work beyond one machine. The
command is ``cagekit amplify``.
"""
