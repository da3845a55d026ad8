"""The library's front door: one public function per command of ``fhnn``, which the CLI only calls.

=================  ===========================  =========================================
command            function                     returns
=================  ===========================  =========================================
``fhnn simulate``  :func:`fhnn.simulate`        a :class:`~fhnn.data.dataset.Dataset`
``fhnn import``    :func:`fhnn.import_table`    a :class:`~fhnn.data.dataset.Dataset`
``fhnn info``      :func:`fhnn.info`            a summary ``dict``
``fhnn train``     :func:`fhnn.train`           a :class:`~fhnn.api.fit.Fit`
``fhnn evaluate``  :func:`fhnn.evaluate`        an :class:`~fhnn.api.evaluate.Evaluation`
``fhnn inspect``   :func:`fhnn.inspect`         an :class:`~fhnn.api.inspect.Inspection`
``fhnn predict``   :func:`fhnn.predict`         a :class:`~fhnn.api.predict.Prediction`
``fhnn reproduce`` :func:`fhnn.reproduce`       a :class:`~fhnn.experiments.reproduce.Summary`
=================  ===========================  =========================================
"""
