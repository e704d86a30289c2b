"""The discrete rod: function spaces, supports and forms put together (model), the rotation charts,
state checks, load coefficients. The physics is pure UFL in cosserat_fem.forms."""
