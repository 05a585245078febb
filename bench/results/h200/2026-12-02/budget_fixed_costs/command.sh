# The runs in this folder used ../budget_converged/command.sh unchanged: bash command.sh sponza 1024 470
# (47ddd2f: sponza_rounds4_47ddd2f/, then 59daecb: sponza/).
