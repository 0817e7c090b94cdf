"""The Stone Soup adapter's sensor lookup on lists of measurement models in which two are equal but
distinct objects (``gpfverify.strategies.lists_with_twins``): Stone Soup's sensors make a new model
object for every scan, so a detection's model is found by identity, else by ``repr`` — and a
``repr`` that two sensors share names neither. The oracle is the drawn design (which positions have
a twin), not the adapter."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from stonesoup.models.measurement.linear import LinearGaussian

from gpfverify.adapters.stonesoup import _sensor_index
from gpfverify.strategies import lists_with_twins, scaled_examples

STATE_DIM = 4
parameters = st.tuples(st.sampled_from([(0, 2), (1, 3), (0,), (2,)]), st.sampled_from([0.5, 1.0, 2.0]))


def _model(params) -> LinearGaussian:
    mapping, variance = params
    return LinearGaussian(ndim_state=STATE_DIM, mapping=mapping, noise_covar=variance * np.eye(len(mapping)))


@settings(max_examples=scaled_examples(0.5))
@given(drawn=lists_with_twins(parameters))
def test_a_sensor_is_found_by_identity_and_by_a_repr_no_other_sensor_shares(drawn):
    params, twins = drawn
    models = [_model(p) for p in params]
    index = _sensor_index(models)
    for i, (p, model) in enumerate(zip(params, models)):
        assert index(model) == i  # the very object: always its own sensor
        rescanned = _model(p)  # a new object with the same properties, as a new scan makes
        assert index(rescanned) == (None if i in twins else i), (i, sorted(twins), params)
    assert index(None) is None
