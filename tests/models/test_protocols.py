"""The planar world answers the batched model seams the filters are typed against."""

from models.protocols import FilterModel, ObservationModel, TransitionModel


def test_the_planar_world_is_a_filter_model(box_world):
    assert isinstance(box_world, TransitionModel)
    assert isinstance(box_world, ObservationModel)
    assert isinstance(box_world, FilterModel)
    assert not isinstance(object(), FilterModel)
